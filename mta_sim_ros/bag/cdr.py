"""CDR serializer of ROS 2 messages from their ros2msg definitions: no rclpy, no generated code.

One encoder for every message the project writes: the offline run, the node and the bag writer
all go through it, so the same message gives the same bytes everywhere. Its output is what
rosbag2 and rmw_fastrtps write, and byte for byte what mcap_ros2's serializer writes for the same
message (``test/test_cdr.py`` compares the two through mcap_ros2's public writer):

* little-endian CDR: the encapsulation header ``00 01 00 00``, then the fields in declaration
  order, nested messages inline;
* every primitive aligned to its own size, counted from after the header, the padding zero;
* ``string``: uint32 length including the NUL, the UTF-8 bytes, a NUL; ``wstring``: uint32 count
  of UTF-16 code units, each as a uint32 (rosidl_typesupport_fastrtps, Jazzy), no terminator;
* ``T[]`` and ``T[<=N]``: uint32 count, then the elements; ``T[N]``: the N elements; a message
  without fields: one zero byte (rosidl adds ``uint8 structure_needs_at_least_one_member``);
* ``char`` is an unsigned byte, as rosidl maps it to IDL (mcap_ros2 agrees for 0..127).

A message is a mapping of field name to value (nested mappings, lists), or any object with the
fields as attributes (an rclpy message, a decoded one). A missing field, or None, takes the
default of its definition (``float64 w 1`` in geometry_msgs/Quaternion), else zero, False, "" or
empty, as mcap_ros2 does. Everything else is checked, not coerced: a value of the wrong kind, an
integer out of its range, a finite float beyond float32, too many elements, an unknown field name
raise one :class:`EncodeError` naming the field (``poses[2].position.x``). Where mcap_ros2 would
silently pad or cut a fixed array or bounded sequence of the wrong length, this raises too.

:class:`Slot` leaves turn an encoding into a template (see :mod:`.template`): the serializer
records the byte offset of each slot as it writes it.
"""
from __future__ import annotations

import functools
import numbers
import struct
from collections.abc import Mapping

import numpy as np

from .definition import FieldSpec, MessageSpec, parse_definition
from .schemas import message_definition, schema_name, split_type_name

#: The encapsulation header: CDR, little-endian, no options.
CDR_LE_HEADER = b"\x00\x01\x00\x00"

# struct format of each fixed-size primitive (little-endian, no alignment of struct's own).
_FORMATS = {"bool": "?", "byte": "B", "char": "B", "int8": "b", "uint8": "B", "int16": "h",
            "uint16": "H", "int32": "i", "uint32": "I", "int64": "q", "uint64": "Q",
            "float32": "f", "float64": "d"}
_INT_RANGES = {name: ((0, 2 ** (8 * struct.calcsize(f)) - 1) if f in "BHIQ"
                      else (-(2 ** (8 * struct.calcsize(f) - 1)), 2 ** (8 * struct.calcsize(f) - 1) - 1))
               for name, f in _FORMATS.items() if name not in ("bool", "float32", "float64")}
_F32 = struct.Struct("<f")
_BOOLS = (bool, np.bool_)
_ZEROS = [bytes(n) for n in range(8)]
_U32 = struct.Struct("<I")

# Builtin definitions for a stored schema that lacks them (mcap_ros2 has the same fallback).
_BUILTIN = {name: MessageSpec(name, (FieldSpec("sec", "int32"), FieldSpec("nanosec", "uint32")))
            for name in ("builtin_interfaces/Time", "builtin_interfaces/Duration")}


class EncodeError(ValueError):
    """A message that does not fit its type. ``str()`` names the type, the field path and why,
    e.g. ``geometry_msgs/msg/PoseArray: poses[2].position.x: expected a real number, got 'a'``."""

    def __init__(self, reason: str):
        super().__init__(reason)
        self.reason, self.path, self.type_name = reason, [], ""

    def within(self, part: str) -> "EncodeError":
        """Prepend a field name (or ``[i]``) to the path; returns self, to re-raise."""
        self.path.insert(0, part)
        return self

    def __str__(self) -> str:
        path = "".join(p if p.startswith("[") else "." + p for p in self.path).lstrip(".")
        return ": ".join(s for s in (self.type_name, path, self.reason) if s)


class Slot:
    """A numeric leaf left open in a template: :class:`.template.CdrTemplate` fills it per message.

    Slots of one ``group`` are filled together: with ``index`` None every slot of the group takes
    the one value given (e.g. every stamp's ``sec``); with indices, the group's slots are numbered
    0..m-1 and take the m values in that order. A slot is written as zero in the template."""

    __slots__ = ("group", "index")

    def __init__(self, group: str, index: int | None = None):
        self.group, self.index = group, index

    def __repr__(self) -> str:
        return f"Slot({self.group!r}, {self.index!r})"


class _Out:
    """The bytes written so far and, when building a template, the slots met: (slot, offset from
    after the header, primitive type)."""

    __slots__ = ("buf", "slots")

    def __init__(self, slots: list | None = None):
        self.buf = bytearray(CDR_LE_HEADER)
        self.slots = slots


def _describe(value) -> str:
    text = repr(value)
    return f"{type(value).__name__} {text[:60] + '...' if len(text) > 60 else text}"


def _pad(buf: bytearray, size: int) -> None:
    """Zero padding up to a multiple of ``size`` counted from after the 4-byte header."""
    pad = (4 - len(buf)) % size
    if pad:
        buf += _ZEROS[pad]


# -- primitives ---------------------------------------------------------------------------------

def _checked(type_: str, value):
    """``value`` as struct packs it for ``type_``, or EncodeError saying why it does not fit."""
    if isinstance(value, _BOOLS):
        if type_ == "bool":
            return bool(value)
        raise EncodeError(f"expected {_kind(type_)}, got {_describe(value)}")
    if type_ == "bool":
        raise EncodeError(f"expected a bool, got {_describe(value)}")
    if type_ == "byte" and isinstance(value, (bytes, bytearray)) and len(value) == 1:
        return value[0]
    if type_ in _INT_RANGES:
        if not isinstance(value, numbers.Integral):
            raise EncodeError(f"expected {_kind(type_)}, got {_describe(value)}")
        low, high = _INT_RANGES[type_]
        if not low <= value <= high:
            raise EncodeError(f"{type_} must be in [{low}, {high}], got {value}")
        return int(value)
    if not isinstance(value, numbers.Real):
        raise EncodeError(f"expected {_kind(type_)}, got {_describe(value)}")
    try:
        value = float(value)
        if type_ == "float32":
            _F32.pack(value)  # raises for a finite value that would round to infinity
    except OverflowError:
        raise EncodeError(f"{value} is beyond the {type_} range (non-finite values are fine)") from None
    return value


def _kind(type_: str) -> str:
    if type_ in ("float32", "float64"):
        return f"a real number ({type_})"
    if type_ == "byte":
        return "a byte (an int in [0, 255] or bytes of length 1)"
    return f"an integer ({type_})"


def _plain_classes(type_: str) -> tuple[type, ...]:
    """The classes struct packs as they are for ``type_`` (anything else goes through _checked)."""
    return {"bool": (bool,), "float32": (float, int), "float64": (float, int)}.get(type_, (int,))


def _scalar(type_: str, default):
    """Writer of one fixed-size primitive."""
    st = struct.Struct("<" + _FORMATS[type_])
    pack, size = st.pack, st.size
    fast = _plain_classes(type_)
    fallback = default if default is not None else (False if type_ == "bool" else 0)

    def write(out: _Out, value) -> None:
        buf = out.buf
        if size > 1:
            _pad(buf, size)
        if value is None:
            value = fallback
        elif value.__class__ not in fast:
            if value.__class__ is Slot:
                value = _record(out, value, type_, len(buf) - 4)
            else:
                value = _checked(type_, value)
        try:
            buf += pack(value)
        except (struct.error, OverflowError):
            raise _range_error(type_, value) from None

    return write


def _range_error(type_: str, value) -> EncodeError:
    try:
        _checked(type_, value)
    except EncodeError as err:
        return err
    return EncodeError(f"{value!r} does not fit {type_}")


def _record(out: _Out, slot: Slot, type_: str, offset: int):
    if out.slots is None:
        raise EncodeError(f"{slot!r} outside a template")
    if type_ == "bool":
        raise EncodeError(f"{slot!r}: slots are for numeric fields, not bool")
    out.slots.append((slot, offset, type_))
    return 0


def _string(type_: str, bound: int | None, default):
    """Writer of one string or wstring."""
    fallback = default if default is not None else ""
    wide = type_ == "wstring"

    def write(out: _Out, value) -> None:
        if value is None:
            value = fallback
        elif not isinstance(value, str):
            raise EncodeError(f"expected a str ({type_}), got {_describe(value)}")
        if bound is not None and len(value) > bound:
            raise EncodeError(f"{len(value)} characters, more than the bound {type_}<={bound}")
        buf = out.buf
        _pad(buf, 4)
        try:
            data = value.encode("utf-16-le" if wide else "utf-8")
        except UnicodeEncodeError as err:
            raise EncodeError(f"not encodable: {err.reason} at character {err.start}") from None
        if wide:
            units = np.frombuffer(data, dtype="<u2")
            buf += _U32.pack(len(units))
            buf += units.astype("<u4").tobytes()
        else:
            buf += _U32.pack(len(data) + 1)
            buf += data
            buf += b"\0"

    return write


# -- arrays -------------------------------------------------------------------------------------

def _items(field: FieldSpec, value):
    """The elements of an array value, or EncodeError if it is no array."""
    if isinstance(value, (list, tuple, np.ndarray)):
        return value
    if isinstance(value, (bytes, bytearray, memoryview)) and field.type in ("uint8", "byte"):
        return value
    if isinstance(value, (str, bytes, Mapping)) or not hasattr(value, "__len__"):
        raise EncodeError(f"expected a sequence ({_array_type(field)}), got {_describe(value)}")
    return list(value)  # array.array, other sequences


def _array_type(field: FieldSpec) -> str:
    if field.array == "fixed":
        return f"{field.type}[{field.size}]"
    return f"{field.type}[{'' if field.size is None else f'<={field.size}'}]"


def _check_length(field: FieldSpec, n: int) -> None:
    if field.array == "fixed" and n != field.size or field.size is not None and n > field.size:
        raise EncodeError(f"{n} elements for {_array_type(field)}")


def _array(field: FieldSpec, element):
    """Writer of an array of ``element`` (a writer), with a count for sequences. Arrays of
    fixed-size primitives outside a template are packed in one go; an element the bulk path
    refuses is found and named by writing the elements one by one."""
    fmt = _FORMATS.get(field.type)
    size = struct.calcsize(fmt) if fmt else 0
    sequence = field.array == "sequence"
    if field.default is not None:
        fallback = list(field.default)
    elif sequence:
        fallback = []
    else:
        fallback = [None] * field.size
    fast = set(_plain_classes(field.type))
    dtype = np.dtype("<" + fmt.replace("?", "b1")) if fmt else None

    def one_by_one(out: _Out, items) -> None:
        for i, item in enumerate(items):
            try:
                element(out, item)
            except EncodeError as err:
                raise err.within(f"[{i}]")

    def bulk(out: _Out, items) -> bool:
        """Pack all items at once; False if they are not all of the plain kinds."""
        buf = out.buf
        if isinstance(items, (bytes, bytearray, memoryview)):
            buf += items
            return True
        if isinstance(items, np.ndarray):
            return _bulk_ndarray(buf, field.type, items, dtype, size)
        if not set(map(type, items)) <= fast:
            return False
        try:
            data = struct.pack(f"<{len(items)}{fmt}", *items)
        except (struct.error, OverflowError):
            return False
        _pad(buf, size)
        buf += data
        return True

    def write(out: _Out, value) -> None:
        items = fallback if value is None else _items(field, value)
        n = len(items)
        _check_length(field, n)
        if sequence:
            _pad(out.buf, 4)
            out.buf += _U32.pack(n)
        if n == 0:
            return
        if fmt is None or out.slots is not None or not bulk(out, items):
            one_by_one(out, items)

    return write


def _bulk_ndarray(buf: bytearray, type_: str, items: np.ndarray, dtype: np.dtype, size: int) -> bool:
    """Pack a numpy array of numbers; False (write one by one, which names the culprit) if its
    dtype or a value does not fit."""
    kind = items.dtype.kind
    if items.ndim != 1:
        raise EncodeError(f"expected a 1-d array, got shape {items.shape}")
    if type_ == "bool":
        ok = kind == "b"
    elif type_ in _INT_RANGES:
        low, high = _INT_RANGES[type_]
        ok = kind in "iu" and (items.size == 0 or (low <= items.min() and items.max() <= high))
    else:
        ok = kind in "fiu"
        if ok and type_ == "float32":
            with np.errstate(over="ignore"):
                ok = bool(np.all(np.isinf(items.astype(dtype)) <= np.isinf(items)))
    if not ok:
        return False
    _pad(buf, size)
    buf += items.astype(dtype).tobytes()
    return True


# -- messages -----------------------------------------------------------------------------------

class _Struct:
    """Writer of one message type: its fields in order."""

    def __init__(self, spec: MessageSpec):
        self.name = spec.name
        self.fields: list[tuple[str, object]] = []  # filled by _compile, after every type exists
        self.names: frozenset[str] = frozenset(f.name for f in spec.fields)

    def write(self, out: _Out, msg) -> None:
        if msg is None:
            msg = {}
        if isinstance(msg, Mapping):
            if not msg.keys() <= self.names:
                unknown = sorted(str(k) for k in msg.keys() - self.names)
                raise EncodeError(f"unknown field(s) {', '.join(unknown)} for {self.name} "
                                  f"(fields: {', '.join(name for name, _ in self.fields) or 'none'})")
            get = msg.get
        elif isinstance(msg, (str, bytes, bytearray, numbers.Number, list, tuple, np.ndarray, Slot)):
            raise EncodeError(f"expected a {self.name} message (a mapping), got {_describe(msg)}")
        else:
            def get(name, obj=msg):
                return getattr(obj, name, None)
        if not self.fields:
            out.buf += b"\0"
            return
        for name, write in self.fields:
            try:
                write(out, get(name))
            except EncodeError as err:
                raise err.within(name)


def _compile(type_name: str, specs: dict[str, MessageSpec]) -> _Struct:
    """The writer of ``type_name`` and, recursively, of every type it uses."""
    structs: dict[str, _Struct] = {}

    def struct_of(name: str, needed_by: str) -> _Struct:
        if name in structs:
            return structs[name]
        spec = specs.get(name) or _BUILTIN.get(name)
        if spec is None:
            raise EncodeError(f"the definition has no type {name} (needed by {needed_by})")
        structs[name] = s = _Struct(spec)
        s.fields = [(f.name, _field_writer(f, name)) for f in spec.fields]
        return s

    def _field_writer(f: FieldSpec, owner: str):
        if f.primitive:
            if f.type in ("string", "wstring"):
                element = _string(f.type, f.string_bound, None if f.array else f.default)
            else:
                element = _scalar(f.type, None if f.array else f.default)
        else:
            element = struct_of(f.type, owner).write
        return _array(f, element) if f.array else element

    return struct_of(type_name, type_name)


class MessageEncoder:
    """CDR encoder of one message type, compiled from a ros2msg definition."""

    def __init__(self, type_name: str, definition: str):
        """
        Args:
            type_name: ``pkg/msg/Name`` (or ``pkg/Name``), the type the definition starts with.
            definition: its ros2msg text (:func:`.schemas.message_definition`, or a bag's schema).

        Raises:
            DefinitionError: the text does not parse.
            EncodeError: a nested type is not defined in it.
        """
        self.type_name = schema_name(type_name)
        try:
            self._root = _compile("/".join(split_type_name(type_name)),
                                  parse_definition(type_name, definition))
        except EncodeError as err:
            err.type_name = self.type_name
            raise

    def encode(self, message) -> bytes:
        """The CDR bytes (with the encapsulation header) of ``message``.

        Raises:
            EncodeError: the message does not fit the type; names the field.
        """
        out = _Out()
        self._write(out, message)
        return bytes(out.buf)

    def encode_with_slots(self, message) -> tuple[bytes, list[tuple[Slot, int, str]]]:
        """The CDR bytes of ``message`` whose leaves may be :class:`Slot` (written as zero), and
        every slot met: (slot, byte offset from after the 4-byte header, primitive type)."""
        out = _Out(slots=[])
        self._write(out, message)
        return bytes(out.buf), out.slots

    def _write(self, out: _Out, message) -> None:
        try:
            self._root.write(out, message)
        except EncodeError as err:
            err.type_name = self.type_name
            raise


@functools.lru_cache(maxsize=None)
def encoder_for(type_name: str) -> MessageEncoder:
    """The encoder of an installed message type, from :func:`.schemas.message_definition` (the
    definition rosbag2 stores). Cached.

    Raises:
        MessageDefinitionNotFound: the type, or a type it uses, is not installed.
        ValueError: malformed type name.
    """
    return MessageEncoder(type_name, message_definition(type_name))


def encode(type_name: str, message) -> bytes:
    """CDR bytes of ``message`` (a mapping of fields) as the installed type ``type_name``."""
    return encoder_for(schema_name(type_name)).encode(message)
