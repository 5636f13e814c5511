"""CDR templates: a message of fixed shape encoded once, then re-encoded per message by writing
new numbers straight into its bytes.

A message whose sizes do not change from one message to the next (the same number of poses, the
same names and frame) has the same bytes everywhere but in its numbers. The template is the
message encoded once by :mod:`.cdr` with :class:`.cdr.Slot` leaves where the numbers go; the
serializer records where it wrote each slot, so nothing is searched for afterwards and the
template's bytes are fully determined by the message (padding is zero). :meth:`CdrTemplate.fill`
then writes values through numpy views of the bytes and copies them out: no message objects, no
walk over the fields, per message.
"""
from __future__ import annotations

import functools
import struct
from collections.abc import Mapping

import numpy as np

from .cdr import EncodeError, MessageEncoder, Slot, encoder_for

# numpy dtype and struct format of each numeric primitive, little-endian.
_LAYOUTS = {"byte": ("<u1", "<B"), "char": ("<u1", "<B"), "int8": ("<i1", "<b"), "uint8": ("<u1", "<B"),
            "int16": ("<i2", "<h"), "uint16": ("<u2", "<H"), "int32": ("<i4", "<i"), "uint32": ("<u4", "<I"),
            "int64": ("<i8", "<q"), "uint64": ("<u8", "<Q"), "float32": ("<f4", "<f"), "float64": ("<f8", "<d")}


class _Group:
    """The slots of one group: where they are, and ``put``, the call that writes their values."""

    def __init__(self, buf: bytearray, name: str, type_: str, offsets: list[int], broadcast: bool):
        dtype, fmt = _LAYOUTS[type_]
        dtype = np.dtype(dtype)
        self.name, self.type, self.broadcast, self.count = name, type_, broadcast, len(offsets)
        if broadcast and self.count == 1:  # one number: struct is quicker than numpy indexing
            self.put = functools.partial(struct.Struct(fmt).pack_into, buf, 4 + offsets[0])
        else:
            view = np.frombuffer(buf, dtype=dtype, count=(len(buf) - 4) // dtype.itemsize, offset=4)
            self.put = functools.partial(view.__setitem__, np.array(offsets, dtype=np.intp) // dtype.itemsize)


class CdrTemplate:
    """The CDR bytes of one message of fixed shape, with numbered holes (slots) for its numbers.

    Usage::

        t = CdrTemplate("std_msgs/msg/Float64", {"data": Slot("data")})
        t.fill(data=2.5)  # == cdr.encode("std_msgs/msg/Float64", {"data": 2.5})

    ``fill`` checks nothing per value beyond numpy's assignment: give each group as many numbers
    as it has slots (one for a broadcast group), of the field's kind.
    """

    def __init__(self, type_name: str, message: Mapping, encoder: MessageEncoder | None = None):
        """Encode ``message`` (its numeric leaves may be :class:`.cdr.Slot`) as ``type_name``.

        Raises:
            EncodeError: the message does not fit the type, or a group's slots are mixed
                (of different field types, indexed and not, indices not 0..m-1 once each).
        """
        encoder = encoder or encoder_for(type_name)
        data, slots = encoder.encode_with_slots(message)
        self.type_name = encoder.type_name
        self.buf = bytearray(data)
        met: dict[str, list[tuple[Slot, int, str]]] = {}
        for slot, offset, type_ in slots:
            met.setdefault(slot.group, []).append((slot, offset, type_))
        self.groups = {name: self._group(name, found) for name, found in met.items()}
        self._puts = {name: group.put for name, group in self.groups.items()}

    def _group(self, name: str, found: list[tuple[Slot, int, str]]) -> _Group:
        def refuse(why: str):
            err = EncodeError(f"slot group {name!r}: {why}")
            err.type_name = self.type_name
            raise err

        types = {type_ for _, _, type_ in found}
        if len(types) > 1:
            refuse(f"slots in fields of different types {sorted(types)}")
        indices = [slot.index for slot, _, _ in found]
        broadcast = all(i is None for i in indices)
        if not broadcast:
            if None in indices:
                refuse("some slots have an index, some not")
            if sorted(indices) != list(range(len(indices))):
                refuse(f"indices must be 0..{len(indices) - 1}, each once")
            found = sorted(found, key=lambda f: f[0].index)
        return _Group(self.buf, name, types.pop(), [offset for _, offset, _ in found], broadcast)

    def size(self, group: str) -> int:
        """How many values ``group`` takes (1 for a broadcast group)."""
        g = self.groups[group]
        return 1 if g.broadcast else g.count

    def put(self, group: str, values) -> None:
        """Write the values of one group into the template's bytes."""
        self.groups[group].put(values)

    def fill(self, **values) -> bytes:
        """The message's bytes with these groups' values (groups not given keep theirs)."""
        puts = self._puts
        for name, v in values.items():
            puts[name](v)
        return bytes(self.buf)


#: A builtin_interfaces/Time whose fields are the broadcast groups "sec" and "nanosec": put it in
#: every header of a template, and ``fill(sec=..., nanosec=...)`` stamps them all.
TIME_SLOTS = {"sec": Slot("sec"), "nanosec": Slot("nanosec")}
