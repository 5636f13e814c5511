"""The fields of every message in a ros2msg definition, parsed for the CDR serializer.

A definition is the text :func:`.schemas.message_definition` builds and rosbag2 stores in a bag's
Schema record: the type's own ``.msg`` file, then one ``MSG: pkg/Name`` block per nested type,
separated by lines of '='. :func:`parse_definition` turns it into one :class:`MessageSpec` per
type, its fields in declaration order (the order CDR writes them). Constants (``int32 ADD=0``) are
no fields and are skipped; defaults (``float64 w 1``) are parsed, because a missing field is
written with its default. The grammar is rosidl's for ``.msg`` files: a comment runs from the first
'#' to the end of the line, the first token is the type (``T``, ``T[]``, ``T[N]``, ``T[<=N]``,
``string<=N``), the second the name, the rest a default value.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

from .schemas import PRIMITIVE_TYPES, BagError, resolve_field_type, split_type_name

# A line of three or more '=' separates the blocks (rosbag2 writes 80).
_BLOCK_SEPARATOR = re.compile(r"^={3,}[ \t]*$", re.MULTILINE)
_MSG_LINE = re.compile(r"\s*MSG:\s*(\S+)[ \t]*(?:\n|$)")
_FIELD_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*")
_TYPE_TOKEN = re.compile(r"(?P<base>[A-Za-z0-9_/]+)(?:<=(?P<bound>\d+))?(?:\[(?P<array><=)?(?P<size>\d*)\])?")

_INT_BITS = {"int8": 8, "int16": 16, "int32": 32, "int64": 64,
             "uint8": 8, "uint16": 16, "uint32": 32, "uint64": 64, "byte": 8, "char": 8}


class DefinitionError(BagError, ValueError):
    """A ros2msg definition that cannot be parsed; the message names the type and the line."""


@dataclass(frozen=True)
class FieldSpec:
    """One field of a message.

    Attributes:
        name: the field name.
        type: a primitive type name (``float64``, ``string``, ...) or a message type ``pkg/Name``.
        array: None for a single value, ``"fixed"`` for ``T[N]``, ``"sequence"`` for ``T[]`` and
            ``T[<=N]``.
        size: N of ``T[N]`` and ``T[<=N]``; None for ``T[]`` and single values.
        string_bound: N of ``string<=N`` / ``wstring<=N``, else None.
        default: the parsed default value (a list for arrays), None if the definition gives none.
    """

    name: str
    type: str
    array: str | None = None
    size: int | None = None
    string_bound: int | None = None
    default: object = None

    @property
    def primitive(self) -> bool:
        return self.type in PRIMITIVE_TYPES


@dataclass(frozen=True)
class MessageSpec:
    """A message type ``pkg/Name`` and its fields in declaration order."""

    name: str
    fields: tuple[FieldSpec, ...]


def parse_definition(type_name: str, text: str) -> dict[str, MessageSpec]:
    """Every message type of a concatenated ros2msg definition, by ``pkg/Name``.

    Args:
        type_name: the type the text defines first, ``pkg/msg/Name`` or ``pkg/Name``.
        text: the definition (see the module docstring).

    Raises:
        DefinitionError: a malformed line or block; the message names type and line.
    """
    specs: dict[str, MessageSpec] = {}
    current = "/".join(split_type_name(type_name))
    for i, block in enumerate(_BLOCK_SEPARATOR.split(text)):
        header = _MSG_LINE.match(block)
        if header:
            try:
                current = "/".join(split_type_name(header.group(1)))
            except ValueError as err:
                raise DefinitionError(f"definition of {type_name}: {err}") from None
            block = block[header.end():]
        elif i > 0:
            raise DefinitionError(f"definition of {type_name}: block {i + 1} has no 'MSG: pkg/Name' line")
        if current not in specs:  # the first definition of a type wins, as for rosbag2's readers
            specs[current] = MessageSpec(current, _parse_fields(current, block))
    return specs


def _parse_fields(type_name: str, text: str) -> tuple[FieldSpec, ...]:
    package = type_name.split("/")[0]
    fields = []
    for line in text.splitlines():
        line = line.split("#", 1)[0].replace("\t", " ").strip()
        if not line:
            continue
        type_token, _, rest = line.partition(" ")
        rest = rest.strip()
        if not rest:
            _fail(type_name, line, "a field needs a type and a name")
        if "=" in rest:
            continue  # a constant, NAME=VALUE: no field (rosidl reads any '=' so)
        name, _, value = rest.partition(" ")
        if not _FIELD_NAME.fullmatch(name):
            _fail(type_name, line, f"{name!r} is not a field name")
        fields.append(_field(type_name, package, line, type_token, name, value.strip() or None))
    return tuple(fields)


def _fail(type_name: str, line: str, why: str):
    raise DefinitionError(f"definition of {type_name}, line {line!r}: {why}")


def _field(type_name: str, package: str, line: str, token: str, name: str,
           default_text: str | None) -> FieldSpec:
    """The FieldSpec of one field line (type token, name, default text)."""
    m = _TYPE_TOKEN.fullmatch(token)
    if not m:
        _fail(type_name, line, f"{token!r} is not a field type")
    base, bound, size = m["base"], m["bound"], m["size"]
    if bound is not None and base not in ("string", "wstring"):
        _fail(type_name, line, "only string and wstring take an upper bound '<=N'")
    if not token.endswith("]"):
        array, size = None, None
    elif size == "":
        if m["array"]:
            _fail(type_name, line, "'[<=]' needs a bound")
        array, size = "sequence", None
    else:
        array, size = ("sequence" if m["array"] else "fixed"), int(size)
        if size <= 0:
            _fail(type_name, line, "an array size must be > 0")
    try:
        resolved = resolve_field_type(base, package) or base
    except ValueError as err:
        _fail(type_name, line, str(err))
    string_bound = int(bound) if bound is not None else None
    if string_bound == 0:
        _fail(type_name, line, "a string bound must be > 0")
    default = None
    if default_text is not None:
        if resolved not in PRIMITIVE_TYPES:
            _fail(type_name, line, "a field of message type takes no default")
        try:
            default = _parse_default(resolved, array, size, string_bound, default_text)
        except ValueError as err:
            _fail(type_name, line, f"default {default_text!r}: {err}")
    return FieldSpec(name, resolved, array, size, string_bound, default)


def _parse_default(type_: str, array: str | None, size: int | None, string_bound: int | None,
                   text: str):
    """The value of a default as written in a .msg file (rosidl's rules)."""
    if array is None:
        return _parse_scalar(type_, text, string_bound)
    if not (text.startswith("[") and text.endswith("]")):
        raise ValueError("an array default must be written [a, b, ...]")
    inner = text[1:-1]
    if type_ in ("string", "wstring"):
        items = _split_strings(inner)
    else:
        items = [item.strip() for item in inner.split(",")] if inner.strip() else []
    if array == "fixed" and len(items) != size:
        raise ValueError(f"{len(items)} elements for an array of {size}")
    if size is not None and len(items) > size:
        raise ValueError(f"{len(items)} elements for a sequence of at most {size}")
    return [_parse_scalar(type_, item, string_bound) for item in items]


def _parse_scalar(type_: str, text: str, string_bound: int | None):
    if type_ == "bool":
        if text.lower() in ("true", "1"):
            return True
        if text.lower() in ("false", "0"):
            return False
        raise ValueError("a bool is true, false, 1 or 0")
    if type_ in _INT_BITS:
        try:
            value = int(text)
        except ValueError:
            value = int(text, 0)  # 0x.., 0o.., 0b..; raises ValueError otherwise
        bits = _INT_BITS[type_]
        low, high = (-(2 ** (bits - 1)), 2 ** (bits - 1) - 1) if type_.startswith("int") else (0, 2 ** bits - 1)
        if not low <= value <= high:
            raise ValueError(f"{type_} must be in [{low}, {high}]")
        return value
    if type_ in ("float32", "float64"):
        return float(text)
    value = _unquote(text)
    if string_bound is not None and len(value) > string_bound:
        raise ValueError(f"longer than the bound {string_bound}")
    return value


def _unquote(text: str) -> str:
    """A string default without its outer quotes, escaped quotes unescaped."""
    for quote in ('"', "'"):
        if len(text) >= 2 and text[0] == quote and text[-1] == quote:
            return text[1:-1].replace("\\" + quote, quote)
    return text


def _split_strings(inner: str) -> list[str]:
    """The elements of a string array default, ``"a, b", 'c', d``: quoted or up to the comma."""
    items, i, n = [], 0, len(inner)
    while True:
        while i < n and inner[i] == " ":
            i += 1
        if i >= n:
            if items:
                raise ValueError("an element is missing after the last ','")
            return items
        if inner[i] in "\"'":
            quote, j = inner[i], i + 1
            while j < n and (inner[j] != quote or inner[j - 1] == "\\"):
                j += 1
            if j >= n:
                raise ValueError("an unclosed quote")
            items.append(inner[i:j + 1])
            i = j + 1
            while i < n and inner[i] == " ":
                i += 1
            if i < n and inner[i] != ",":
                raise ValueError("text after a quoted element")
        else:
            j = inner.find(",", i)
            j = n if j < 0 else j
            items.append(inner[i:j].strip())
            i = j
        if i >= n:
            return items
        i += 1  # the comma
