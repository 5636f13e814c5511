"""The rules every input of the package is checked by, written once: the fault's one-line form,
finite numbers and ranges, the bounds that keep a run finite, a YAML reader that cannot be made
to hang or exhaust memory, unknown names with the closest known one, and output paths.

The bottom room: it imports nothing of the package, so the loader (physics/), the node's
parameters (params.py), the bag readers (runlog.py) and the commands (tools/, cli.py) all take
their rules from here. Each fault is an :class:`InputError` whose message is one line,

    FIELD: VALUE in LOCATION of FILE must be RULE

(LOCATION and FILE where there are some), e.g. ``publish_rate: 0.5 in top level of
scenes/x.yaml must be in [1, 1000] Hz``; a command prints it and exits with ``EXIT_INPUT``.
"""
from __future__ import annotations

import difflib
import math
import os
import re
import reprlib
import stat
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterable, NoReturn

import yaml

#: exit code of a command refusing an input (a file, an argument, a parameter, bag metadata)
EXIT_INPUT = 2


class InputError(ValueError):
    """An input breaks a rule; the message (one line) names the field, value, place and rule."""


def fault_message(field: str, value: str, rule: str, where: str = "", source: str = "") -> str:
    """``FIELD: VALUE in WHERE of SOURCE must be RULE`` (the parts without a value left out)."""
    place = (f" in {where}" if where else "") + (f" of {source}" if source else "")
    return one_line(f"{field}: " * bool(field) + f"{value}{place} must be {rule}")


def fail(field: str, shown: str, rule: str, where: str = "", source: str = "",
         error: type[InputError] = InputError) -> NoReturn:
    """Raise ``error`` for ``field`` whose value reads ``shown`` (a value goes through :func:`show`
    first; a description such as "not found" as it is)."""
    raise error(fault_message(field, shown, rule, where, source))


def one_line(text: str) -> str:
    """``text`` with its line breaks turned into spaces: a fault is one line."""
    return " ".join(text.split("\n")).replace("\r", " ")


# --------------------------------------------------------------------------- values in messages

SHOW_WIDTH = 60  # characters of a value in a message


class _Shown(reprlib.Repr):
    """reprlib with small limits: showing a value costs little whatever its size (an expanded
    YAML alias, a list of millions of numbers)."""

    def __init__(self):
        super().__init__()
        self.maxlevel, self.maxlist, self.maxtuple, self.maxdict = 3, 8, 8, 4
        self.maxstring, self.maxother = SHOW_WIDTH, SHOW_WIDTH

    def repr_int(self, x, level):
        if x.bit_length() > 200:  # past ~1e60: never convert a huge int to digits
            return f"an integer of about {int(x.bit_length() * math.log10(2)) + 1} digits"
        return super().repr_int(x, level)


_SHOWN = _Shown()


def show(value: object) -> str:
    """A value as it reads in YAML (strings quoted), at most SHOW_WIDTH characters, at a cost
    bounded whatever its size; other objects (a "missing" marker, a date) by their ``str``."""
    if isinstance(value, float):
        text = repr(value) if isinstance(value, HugeNumber) else str(value)
    elif isinstance(value, (str, bytes, int, list, tuple, dict, set, frozenset, type(None))):
        text = _SHOWN.repr(value)
    else:
        text = str(value)
    text = one_line(text)
    return text if len(text) <= SHOW_WIDTH else text[:SHOW_WIDTH - 3] + "..."


# --------------------------------------------------------------------------- numbers and rules


def is_number(value: object) -> bool:
    """An int or float (not a bool)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def is_finite(value: object) -> bool:
    """A number that is finite as a float (an int beyond float range is not)."""
    if not is_number(value):
        return False
    if isinstance(value, int):
        return abs(value) <= sys.float_info.max
    return math.isfinite(value)


@dataclass(frozen=True)
class Rule:
    """A condition on a number and the words that finish "must be ..."."""

    text: str
    test: Callable[[float], bool]


ANY = Rule("finite", lambda x: True)
POSITIVE = Rule("> 0", lambda x: x > 0)
NON_NEGATIVE = Rule(">= 0", lambda x: x >= 0)
#: a frame name as tf2 takes it: no leading '/', no spaces or control characters, not empty, and
#: short (it is in every message the node publishes): the node's frame_id, the URDF's frames
FRAME_ID = Rule("a frame name: 1 to 256 printable characters, no spaces, not starting with '/'",
                lambda v: 0 < len(v) <= 256 and v.isprintable() and not any(c.isspace() for c in v)
                and not v.startswith("/"))


@dataclass(frozen=True)
class Range(Rule):
    """``low <= x <= high`` (the node's parameter ranges are these), with a unit for messages."""

    low: float = 0.0
    high: float = 0.0

    @classmethod
    def of(cls, low: float, high: float, unit: str = "") -> "Range":
        text = f"in [{low:g}, {high:g}]" + (f" {unit}" if unit else "")
        return cls(text, lambda x: low <= x <= high, low, high)


def check_number(value: object, rule: Rule = ANY) -> str:
    """'' if ``value`` is a finite number obeying ``rule``, else the rule it breaks (the words
    after "must be")."""
    if not is_number(value):
        return "a number" if rule is ANY else f"a number {rule.text}"
    if not is_finite(value):
        return "a finite number" if rule is ANY else f"a finite number {rule.text}"
    return "" if rule.test(value) else rule.text


# --------------------------------------------------------------------------- bounds of a run

#: publish (tick) rate of a scene, of the node and of every command's --rate, Hz
PUBLISH_RATE = Range.of(1.0, 1000.0, "Hz")
#: ticks of one run (a scene's duration x publish_rate, or a command's): 10^7 is 28 h at 100 Hz
MAX_TICKS = 10_000_000
#: integrator steps in one tick (step >= tick / MAX_STEPS_PER_TICK, sub-steps for stability included)
MAX_STEPS_PER_TICK = 10_000
#: integrator steps of one run
MAX_RUN_STEPS = 100_000_000
#: entries of a table (steering, speed; an expanded manoeuvre included)
MAX_TABLE = 100_000
#: simulated seconds a command may be asked to run (11.6 days)
MAX_DURATION = 1e6
DURATION = Rule(f"in (0, {MAX_DURATION:g}] s", lambda x: 0 < x <= MAX_DURATION)
#: repeats, rounds, ticks a command counts
COUNT = Range.of(1, 1_000_000)


def step_rule(rate: float) -> Rule:
    """An integrator step for ticks of 1/rate s: in [tick / MAX_STEPS_PER_TICK, tick]."""
    tick = 1.0 / rate
    low = tick / MAX_STEPS_PER_TICK
    return Rule(f"in [1/publish_rate / {MAX_STEPS_PER_TICK}, 1/publish_rate] = [{low:.6g}, {tick:.6g}] s",
                lambda x: low * (1 - 1e-12) <= x <= tick * (1 + 1e-12))


def step_floor(rate: float) -> Rule:
    """An integrator step that a tick of 1/rate s can take: at least tick / MAX_STEPS_PER_TICK (a
    longer step than the tick is cut to it)."""
    low = 1.0 / rate / MAX_STEPS_PER_TICK
    return Rule(f">= 1/publish_rate / {MAX_STEPS_PER_TICK} = {low:.6g} s", lambda x: x >= low * (1 - 1e-12))


def steps_per_tick(tick: float, step: float) -> int:
    """Steps a fixed-step method takes over one tick (the tick split into equal parts); at most
    10^18 (a step of 0 or one that underflows against the tick)."""
    ratio = tick / step if step > 0 else math.inf
    return max(1, math.ceil(ratio - 1e-9)) if ratio < 1e18 else 10**18


def tick_count(duration: float, rate: float) -> str:
    """'' if a run of ``duration`` s at ``rate`` Hz is within MAX_TICKS ticks, else the rule it
    breaks, with its numbers."""
    ticks = duration * rate
    if math.floor(ticks + 1e-9) < 1:
        return (f"at least one tick: {duration:.6g} s x {rate:.6g} Hz = {ticks:.3g} ticks (at least {1.0 / rate:.6g} s "
                "at this rate)")
    if ticks <= MAX_TICKS:
        return ""
    return (f"at most {MAX_TICKS:.0e} ticks: {duration:.6g} s x {rate:.6g} Hz = {ticks:.3g} ticks "
            f"(at most {MAX_TICKS / rate:.6g} s at this rate)")


def step_count(duration: float, rate: float, step: float) -> str:
    """'' if a run of ``duration`` s at ``rate`` Hz with integrator step ``step`` s is within
    MAX_RUN_STEPS steps, else the rule it breaks, with its numbers."""
    per_tick = steps_per_tick(1.0 / rate, step)
    steps = math.floor(duration * rate + 1e-9) * per_tick
    if steps <= MAX_RUN_STEPS:
        return ""
    return (f"at most {MAX_RUN_STEPS:.0e} integrator steps in a run: {duration * rate:.3g} ticks x {per_tick} "
            f"steps of {step:.3g} s = {steps:.3g} steps")


def run_size(duration: float, rate: float, step: float) -> str:
    """'' if a run is within MAX_TICKS ticks and MAX_RUN_STEPS steps, else the rule it breaks."""
    return tick_count(duration, rate) or step_count(duration, rate, step)


# --------------------------------------------------------------------------- names


def closest(name: object, known: Iterable[str]) -> str:
    """'; did you mean X?' for the known name most like ``name`` ('' if none is close)."""
    match = difflib.get_close_matches(str(name)[:200], list(known), n=1, cutoff=0.6)
    return f"; did you mean {match[0]}?" if match else ""


def unknown_name_rule(name: object, known: Iterable[str], what: str = "field",
                      spelled: Iterable[str] | None = None) -> str:
    """The rule an unknown key breaks: one of the known ones (listed as ``spelled``, if given),
    and the closest of them."""
    known = tuple(known)
    listed = ", ".join(spelled if spelled is not None else known)
    if not listed:
        return f"removed: none is taken here (no {what} is known at this place)"
    return f"removed or renamed: unknown {what}; expected one of {listed}{closest(name, known)}"


# --------------------------------------------------------------------------- YAML

#: characters of a YAML document (train, scene, params file, a bag's recorded texts)
MAX_YAML_CHARS = 1 << 18
#: nesting of mappings and lists
MAX_YAML_DEPTH = 32
#: aliases (*name) in one document
MAX_YAML_ALIASES = 64
#: nodes of a document with every alias expanded
MAX_YAML_NODES = 100_000
#: characters of an integer literal read as such (longer ones are beyond float range)
MAX_INT_CHARS = 1000


class HugeNumber(float):
    """An integer literal beyond float range: infinite as a float (so every finite-number rule
    refuses it), shown as written (shortened)."""

    def __new__(cls, literal: str):
        self = super().__new__(cls, -math.inf if literal.lstrip().startswith("-") else math.inf)
        self.literal = literal
        return self

    def __repr__(self) -> str:
        text = self.literal
        return text if len(text) <= 24 else f"{text[:12]}...({len(text)} characters)"

    __str__ = __repr__


class YamlLimit(yaml.YAMLError):
    """A document breaks a bound (depth, aliases, expanded size): field, value and rule at a mark."""

    def __init__(self, field: str, value: str, rule: str, mark):
        super().__init__(f"{field}: {value} must be {rule}")
        self.field, self.value, self.rule, self.mark = field, value, rule, mark


class RepeatedKey(yaml.YAMLError):
    def __init__(self, key: str, mark):
        super().__init__(key)
        self.key, self.mark = key, mark


class BoundedLoader(yaml.SafeLoader):
    """Safe YAML that refuses repeated keys, reads ``1e-8`` as a float, reads an integer beyond
    float range as a :class:`HugeNumber`, and refuses nesting deeper than MAX_YAML_DEPTH, more
    than MAX_YAML_ALIASES aliases, a recursive alias and more than MAX_YAML_NODES nodes with the
    aliases expanded, all while composing: before anything is expanded."""

    def __init__(self, stream):
        super().__init__(stream)
        self._depth = 0
        self._nodes = 0
        self._aliases = 0
        self._open: set[str] = set()  # anchors being composed (an alias to one is recursive)
        self._weight: dict[str, int] = {}  # anchor -> nodes it stands for, expanded

    def compose_node(self, parent, index):
        event = self.peek_event()
        if isinstance(event, yaml.AliasEvent):
            self._alias(event)
            return super().compose_node(parent, index)
        if self._depth >= MAX_YAML_DEPTH:
            raise YamlLimit("nesting", f"more than {MAX_YAML_DEPTH} levels", f"at most {MAX_YAML_DEPTH} levels "
                            "of mappings and lists", event.start_mark)
        before = self._count(1, event.start_mark)
        anchor = event.anchor
        if anchor is not None:
            self._open.add(anchor)
        self._depth += 1
        try:
            node = super().compose_node(parent, index)
        finally:
            self._depth -= 1
        if anchor is not None:
            self._open.discard(anchor)
            self._weight[anchor] = self._nodes - before
        return node

    def _alias(self, event) -> None:
        """Count an alias and the nodes it expands to; refuse past the bounds."""
        self._aliases += 1
        if self._aliases > MAX_YAML_ALIASES:
            raise YamlLimit("aliases", f"more than {MAX_YAML_ALIASES}", f"at most {MAX_YAML_ALIASES} per document",
                            event.start_mark)
        if event.anchor in self._open:
            raise YamlLimit(f"*{event.anchor}", "an alias inside its own anchor", "an alias to a finished node",
                            event.start_mark)
        self._count(self._weight.get(event.anchor, 0), event.start_mark)

    def _count(self, nodes: int, mark) -> int:
        """Add ``nodes`` to the expanded size; returns the size before."""
        before = self._nodes
        self._nodes += nodes
        if self._nodes > MAX_YAML_NODES:
            raise YamlLimit("document", f"more than {MAX_YAML_NODES} values with its aliases expanded",
                            f"at most {MAX_YAML_NODES} values", mark)
        return before

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            if isinstance(key_node, yaml.ScalarNode) and key_node.tag != "tag:yaml.org,2002:merge":
                if key_node.value in seen:
                    raise RepeatedKey(key_node.value, key_node.start_mark)
                seen.add(key_node.value)
        return super().construct_mapping(node, deep)

    def construct_yaml_int(self, node):
        literal = self.construct_scalar(node)
        if len(literal) > MAX_INT_CHARS:
            return HugeNumber(literal)
        value = super().construct_yaml_int(node)
        return HugeNumber(literal) if abs(value) > sys.float_info.max else value


BoundedLoader.add_constructor("tag:yaml.org,2002:int", BoundedLoader.construct_yaml_int)
BoundedLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"),
)


def parse_yaml(text: str, source: str, error: type[InputError] = InputError) -> object:
    """The value of one YAML document (None if empty), every bound checked; a fault raises
    ``error`` naming ``source``."""
    if not isinstance(text, str):
        fail("file", f"a {type(text).__name__}", "YAML text", "document", source, error)
    if len(text) > MAX_YAML_CHARS:
        fail("file", f"{len(text)} characters", f"at most {MAX_YAML_CHARS} characters", "document", source, error)
    try:
        return yaml.load(text, Loader=BoundedLoader)
    except RepeatedKey as err:
        fail(err.key, "given twice", "given once", line_of(err.mark), source, error)
    except YamlLimit as err:
        raise error(fault_message(err.field, err.value, err.rule, line_of(err.mark), source)) from None
    except yaml.reader.ReaderError as err:
        character = chr(err.character) if isinstance(err.character, int) else err.character
        fail("yaml", f"character {character!r} at position {err.position}", "printable text", "document", source,
             error)
    except yaml.MarkedYAMLError as err:
        mark = err.problem_mark or err.context_mark
        raise error(fault_message("yaml", str(err.problem)[:200], "valid YAML syntax",
                                  line_of(mark) if mark else "document", source)) from None
    except yaml.YAMLError as err:
        raise error(fault_message("yaml", str(err)[:200], "valid YAML syntax", "document", source)) from None


def line_of(mark) -> str:
    return f"line {mark.line + 1}, column {mark.column + 1}"


def stream_kind(path: str | os.PathLike) -> str:
    """'a named pipe' or 'a socket' where ``path`` is one (reading it would wait for a writer), else ''."""
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):
        return ""  # opening it says why
    return "a named pipe" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode) else ""


def read_text(path: str | os.PathLike, error: type[InputError] = InputError) -> str:
    """The UTF-8 text of a file of at most MAX_YAML_CHARS characters (never reading more than
    that, whatever the file's size); a fault names the file."""
    source = str(path)
    if stream_kind(path):
        fail("file", stream_kind(path), "a YAML file (reading one waits for a writer)", "document", source, error)
    try:
        with open(path, "rb") as stream:
            data = stream.read(4 * MAX_YAML_CHARS + 1)
    except FileNotFoundError:
        fail("file", "not found", "an existing YAML file", "document", source, error)
    except (OSError, ValueError) as err:
        fail("file", f"unreadable ({err})", "a readable UTF-8 YAML file", "document", source, error)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as err:
        fail("file", f"unreadable ({err})", "a readable UTF-8 YAML file", "document", source, error)
    if len(text) > MAX_YAML_CHARS or len(data) > 4 * MAX_YAML_CHARS:
        fail("file", f"more than {MAX_YAML_CHARS} characters", f"at most {MAX_YAML_CHARS} characters", "document",
             source, error)
    return text


def read_limited(path: str | os.PathLike, limit: int, what: str, error: type[InputError] = InputError) -> bytes:
    """The bytes of a file of at most ``limit`` bytes (never reading more than that, whatever its
    size); a fault names the file and says it is ``what`` that was wanted ("a GeoJSON field file")."""
    source = str(path)
    if stream_kind(path):
        fail("file", stream_kind(path), f"{what} (reading one waits for a writer)", "document", source, error)
    try:
        with open(path, "rb") as stream:
            data = stream.read(limit + 1)
    except FileNotFoundError:
        fail("file", "not found", f"an existing {what}", "document", source, error)
    except (OSError, ValueError) as err:
        fail("file", f"unreadable ({err})", f"a readable {what}", "document", source, error)
    if len(data) > limit:
        fail("file", f"more than {limit} bytes", f"at most {limit} bytes", "document", source, error)
    return data


def read_mapping(path: str | os.PathLike, error: type[InputError] = InputError) -> dict:
    """The top-level mapping of a YAML file (see parse_mapping)."""
    return parse_mapping(read_text(path, error), str(path), error)


def parse_mapping(text: str, source: str, error: type[InputError] = InputError) -> dict:
    """The top-level mapping of a YAML document; empty or another kind of value is a fault."""
    data = parse_yaml(text, source, error)
    if data is None:
        fail("file", "empty", "a YAML mapping of fields", "document", source, error)
    if not isinstance(data, dict):
        fail("file", f"a {type(data).__name__}", "a YAML mapping of fields", "document", source, error)
    return data


# --------------------------------------------------------------------------- output paths


def _probe_folder(folder: Path) -> str:
    """'' if a file can be made in ``folder`` (made with its parents if missing), else why not."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".mta_probe_"):
            pass
    except (OSError, ValueError) as err:
        return f"{folder} cannot be written ({err.strerror if isinstance(err, OSError) and err.strerror else err})"
    return ""


def _file_in_the_way(path: Path) -> Path | None:
    """The nearest existing ancestor of ``path`` if it is not a folder, else None."""
    for parent in path.parents:
        if parent.exists():
            return None if parent.is_dir() else parent
    return None


def _file_problem(p: Path) -> str:
    """Why ``p`` cannot be written as a file ('' if it can, so far as can be seen without writing)."""
    if p.is_dir():
        return "a file path: it is a folder"
    blocker = _file_in_the_way(p)
    if blocker is not None:
        return f"a path whose folder can be made: {blocker} is a file"
    if p.exists() and not os.access(p, os.W_OK):
        return "a writable file: it is read-only"
    return ""


def _folder_problem(p: Path) -> str:
    """Why ``p`` cannot be a folder to write into ('' if it can, so far as can be seen)."""
    if p.exists() and not p.is_dir():
        return "a folder: it is a file"
    blocker = _file_in_the_way(p)
    if blocker is not None:
        return f"a folder that can be made: {blocker} is a file"
    return ""


def _checked_path(path: str | os.PathLike, field: str, problem_of: Callable[[Path], str], probe: Callable[[Path], Path],
                  made: str) -> Path:
    """``path`` as a Path once ``problem_of`` finds nothing and a file can be made in ``probe(path)``."""
    if not str(path):
        fail(field, show(str(path)), "a path")
    p = Path(path)
    try:
        problem = "a path without a NUL character" if "\0" in str(path) else problem_of(p)
    except (OSError, ValueError) as err:  # a name too long, ...
        problem = f"a usable path ({err.strerror if isinstance(err, OSError) and err.strerror else err})"
    if not problem:
        found = _probe_folder(probe(p))
        problem = f"{made}: {found}" if found else ""
    if problem:
        fail(field, show(str(path)), problem)
    return p


def output_file(path: str | os.PathLike, field: str) -> Path:
    """``path`` checked as a file to write, before any work: not a folder, no file where a folder
    of it should be, and a file can be made in its folder (made if missing). Raises InputError."""
    return _checked_path(path, field, _file_problem, lambda p: p.parent, "a path that can be created")


def distinct_output(path: Path, field: str, inputs) -> Path:
    """``path`` (an output_file) checked against the command's ``inputs`` (paths, None skipped): none
    of them may be the same file (the same device and inode where both exist, else the same resolved
    path, so a link or another spelling of an input is caught too). Raises InputError."""
    for source in inputs:
        if source is None:
            continue
        try:
            same = os.path.samefile(path, source)
        except OSError:  # one of them does not exist (yet): compare where they would be
            same = Path(path).resolve() == Path(source).resolve()
        if same:
            fail(field, show(str(path)), f"another file than the input {source}")
    return path


def output_folder(path: str | os.PathLike, field: str) -> Path:
    """``path`` checked as a folder to write into: not a file, no file on its way, writable
    (made if missing). Raises InputError."""
    return _checked_path(path, field, _folder_problem, lambda p: p, "a folder that can be created")


# --------------------------------------------------------------------------- command-line numbers


def number_arg(rule: Rule = ANY, kind: type = float) -> Callable[[str], float]:
    """An argparse ``type``: the text as a ``kind`` (float or int) that is finite and obeys
    ``rule``; else the one-line reason (argparse adds the option's name)."""
    import argparse

    def parse(text: str):
        shown = text if len(text) <= SHOW_WIDTH and text.isprintable() else show(text)
        try:
            value = kind(text)
        except (TypeError, ValueError):
            raise argparse.ArgumentTypeError(f"{shown} must be {'an integer' if kind is int else 'a number'} "
                                             f"{'' if rule is ANY else rule.text}".rstrip()) from None
        problem = check_number(value, rule)
        if problem:
            raise argparse.ArgumentTypeError(f"{shown} must be {problem}")
        return value

    parse.__name__ = kind.__name__  # argparse names the type in its own messages
    return parse


def path_arg(check: Callable[[str, str], Path]) -> Callable[[str], str]:
    """An argparse ``type`` for an output path: ``check`` (output_file or output_folder) at parse
    time, so a bad path is refused before any work; the text is kept as given."""
    import argparse

    def parse(text: str) -> str:
        try:
            check(text, "")
        except InputError as err:
            raise argparse.ArgumentTypeError(str(err)) from None
        return text

    parse.__name__ = "path"
    return parse
