"""ROS 2 message definitions in the form rosbag2 (Jazzy) stores them in MCAP.

rosbag2's MCAP storage writes one Schema record per message type:

* ``name``: ``pkg/msg/Name`` (e.g. ``geometry_msgs/msg/PoseArray``),
* ``encoding``: ``ros2msg``,
* ``data``: the *concatenated* definition built by rosbag2_cpp's
  ``LocalMessageDefinitionSource::get_full_text``: the type's own ``.msg`` file
  verbatim, then for every nested type, each once and depth-first, a block::

      \\n
      ================================================================================\\n
      MSG: pkg/Name\\n
      <that type's .msg file verbatim>

  The nested types of one ``.msg`` file are visited in sorted order of their
  ``pkg/Name`` (rosbag2 collects them in a ``std::set``), and a type already
  emitted anywhere earlier is not repeated.

This module rebuilds exactly that text from the ``.msg`` files installed under
``<prefix>/share/<pkg>/msg/``; it needs no rclpy, so it works both offline
(``mcap`` wheels only) and inside the ROS node. A type that no share directory has is read from
the copies shipped in the package (``bag/msg/<pkg>/<Name>.msg``, the Jazzy files of every type the
package writes, byte for byte): where no ROS is installed at all the bags get the same schemas,
and a ROS install still reads its own files.
"""

import functools
import os
import re
import sys
from importlib import resources
from pathlib import Path

#: Line that separates the nested definitions (80 '=' characters).
SEPARATOR = "=" * 80

#: ROS 2 builtin field types (rosidl); ``wstring`` included, unlike rosbag2.
PRIMITIVE_TYPES = frozenset({
    "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16",
    "uint16", "int32", "uint32", "int64", "uint64", "string", "wstring",
})

# The first token of each line of a .msg file, without any array suffix
# (``T[]``, ``T[N]``, ``T[<=N]``); the same pattern rosbag2_cpp uses.  Comment
# lines start with '#' and bounded strings (``string<=N``) do not match, which
# is fine: neither names a nested message type.
_FIELD_TYPE_RE = re.compile(r"(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+")

_NAME_RE = re.compile(r"[A-Za-z][A-Za-z0-9_]*")


class BagError(Exception):
    """Base class of every error raised by the ``mta_sim_ros.bag`` layer."""


class MessageDefinitionNotFound(BagError, LookupError):
    """A ``.msg`` file needed for a message definition is not installed."""


def split_type_name(type_name: str) -> tuple[str, str]:
    """Split ``pkg/msg/Name`` or ``pkg/Name`` into ``(pkg, Name)``.

    Raises:
        ValueError: ``type_name`` is not a ROS 2 message type name.
    """
    parts = type_name.split("/")
    if len(parts) == 3 and parts[1] == "msg":
        parts = [parts[0], parts[2]]
    if len(parts) != 2 or not all(_NAME_RE.fullmatch(p) for p in parts):
        raise ValueError(
            f"{type_name!r} is not a ROS 2 message type name "
            "(expected 'pkg/msg/Name' or 'pkg/Name')")
    return parts[0], parts[1]


def schema_name(type_name: str) -> str:
    """Return the MCAP schema name ``pkg/msg/Name`` for a message type."""
    pkg, name = split_type_name(type_name)
    return f"{pkg}/msg/{name}"


def share_dirs() -> list[Path]:
    """Directories searched for ``<pkg>/msg/<Name>.msg``, in priority order.

    ``$AMENT_PREFIX_PATH`` entries first (a sourced ROS install or overlay),
    then the running interpreter's prefix (``sys.prefix/share``, where the
    ROS Jazzy PyPI wheels install their interface files).
    """
    prefixes = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    prefixes.append(sys.prefix)
    dirs = []
    for prefix in prefixes:
        share = Path(prefix) / "share"
        if share not in dirs:
            dirs.append(share)
    return dirs


def vendored_dir():
    """The package's own copies of the Jazzy ``.msg`` files it writes, ``<pkg>/<Name>.msg``
    (bag/msg/README.md): read only for a type that no share dir has."""
    return resources.files(__package__) / "msg"


@functools.lru_cache(maxsize=None)
def type_hash(type_name: str) -> str:
    """The RIHS01 hash ROS 2 Jazzy gives a message type (what rmw compares between a publisher and
    a subscription; rosbag2 keeps it as a channel's ``topic_type_hash``), "" for a type the package
    does not write. From msg/type_hashes.json: the hashes Jazzy's rosidl put in each type's
    ``share/<pkg>/msg/<Name>.json`` (test/test_bag.py holds them to the installed files)."""
    import json

    table = json.loads((vendored_dir() / "type_hashes.json").read_text())
    pkg, name = split_type_name(type_name)
    return table.get(f"{pkg}/msg/{name}", "")


def _read_msg_file(pkg: str, name: str, needed_by: str | None) -> str:
    """Return the verbatim text of ``pkg/msg/Name.msg`` from the first share dir, else from the
    vendored copies."""
    searched = share_dirs()
    for share in searched:
        path = share / pkg / "msg" / f"{name}.msg"
        if path.is_file():
            # newline="" keeps the file byte-exact (no newline translation).
            with open(path, encoding="utf-8", newline="") as f:
                return f.read()
    vendored = vendored_dir() / pkg / f"{name}.msg"
    if vendored.is_file():
        return vendored.read_bytes().decode("utf-8")
    context = f" (needed by {needed_by})" if needed_by else ""
    raise MessageDefinitionNotFound(
        f"no message definition for {pkg}/msg/{name}{context}: "
        f"{pkg}/msg/{name}.msg not found under any of "
        f"{', '.join(str(d) for d in searched)}, nor among the package's own copies")


def resolve_field_type(token: str, package: str) -> str | None:
    """Resolve a field type token of a ``.msg`` file in ``package``.

    Returns ``pkg/Name`` for a message type, or None for a builtin type.
    A bare name refers to the same package, except ``Header``, which is
    ``std_msgs/Header``; ``pkg/msg/Name`` is normalised to ``pkg/Name``.
    """
    if token in PRIMITIVE_TYPES:
        return None
    if "/" not in token:
        return "std_msgs/Header" if token == "Header" else f"{package}/{token}"
    pkg, name = split_type_name(token)
    return f"{pkg}/{name}"


def nested_types(msg_text: str, package: str) -> list[str]:
    """Message types (``pkg/Name``) used by the fields of one ``.msg`` file, sorted."""
    found = (resolve_field_type(m.group(1), package)
             for m in _FIELD_TYPE_RE.finditer(msg_text))
    return sorted({t for t in found if t is not None})


@functools.lru_cache(maxsize=None)
def message_definition(type_name: str) -> str:
    """Full ``ros2msg`` text of a message type, exactly as rosbag2 Jazzy stores it.

    Args:
        type_name: ``pkg/msg/Name`` or ``pkg/Name``, e.g. "geometry_msgs/msg/PoseArray".

    Raises:
        MessageDefinitionNotFound: the ``.msg`` file of the type or of a nested
            type is not installed; the message names the missing type.
        ValueError: malformed type name.

    Results are cached (``message_definition.cache_clear()`` resets the cache).
    """
    root = "/".join(split_type_name(type_name))
    seen: set[str] = set()

    def full_text(type_pkg_name: str, needed_by: str | None) -> str:
        pkg, name = type_pkg_name.split("/")
        text = _read_msg_file(pkg, name, needed_by)
        for dep in nested_types(text, pkg):
            if dep not in seen:
                seen.add(dep)
                text += f"\n{SEPARATOR}\nMSG: {dep}\n" + full_text(dep, type_pkg_name)
        return text

    return full_text(root, None)
