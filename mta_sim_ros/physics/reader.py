"""Reading one YAML mapping field by field, each value checked by a rule: the reader the train and
scene loader (loader.py, by the fields schema.py declares) and the sweep specs (sweep/spec.py) use.

Every fault raises :class:`SpecError` with one line ``FIELD: VALUE in LOCATION of FILE must be
RULE`` (validate.fault_message): FIELD spelled and VALUE shown as the user wrote them (a KEY_deg
field in degrees), LOCATION a path into the document (``top level``, ``carts[1]``,
``forces.traction``).
"""
from __future__ import annotations

import math
import os
from typing import Any, Iterable, NoReturn, Optional, Union

from .. import validate
from ..validate import ANY, Rule


class SpecError(validate.InputError):
    """A train or scene file breaks a rule; the message says which field, where and why."""


#: the default meaning "the field must be given"
REQUIRED = object()


def fail(field: str, value: str, where: str, source: str, rule: str) -> NoReturn:
    raise SpecError(validate.fault_message(field, value, rule, where, source))


def read(path: Union[str, os.PathLike]) -> tuple[dict, str]:
    """The top-level mapping of a YAML file, and the path as given (for messages); the file's
    size, nesting and aliases are bounded (validate.py)."""
    source = str(path)
    return validate.read_mapping(path, SpecError), source


def parse(text: str, source: str) -> tuple[dict, str]:
    """The top-level mapping of a YAML text, and its source."""
    return validate.parse_mapping(text, source, SpecError), source


class Missing:
    """Stands for the value of a field that was not given, in messages."""

    def __str__(self) -> str:
        return "(missing)"


show = validate.show
is_number = validate.is_number


class Section:
    """One YAML mapping being read: its fields are taken one by one, each checked.

    ``fields`` are the allowed keys; each key in ``angles`` may instead be given in degrees
    as KEY_deg (a number or list of numbers), converted to radians here.
    """

    def __init__(self, data: dict, path: str, source: str, fields: Optional[Iterable[str]], angles: Iterable[str] = ()):
        self.path, self.source = path, source
        self.where = path or "top level"
        self.raw = data
        self.angles = tuple(angles)
        self.degrees: dict[str, Any] = {}  # key -> value as given in degrees
        self.values = dict(data)
        for key in self.angles:
            self._convert_degrees(key)
        if fields is not None:
            self.check_fields(fields)

    def check_fields(self, fields: Iterable[str]) -> None:
        """Fault on the first key that is not one of ``fields`` (a typo, most likely)."""
        allowed = tuple(fields)
        for key, value in self.values.items():
            if key not in allowed:
                spelled = [f"{k}[_deg]" if k in self.angles else k for k in allowed]
                name = key if isinstance(key, str) and len(key) <= validate.SHOW_WIDTH else show(key)
                self.fail(name, value, validate.unknown_name_rule(key, allowed, spelled=spelled))

    def _convert_degrees(self, key: str) -> None:
        deg_key = key + "_deg"
        if deg_key not in self.values:
            return
        value = self.values.pop(deg_key)
        if key in self.values:
            self.fail(deg_key, value, f"given alone: {key} (radians) is given too")
        if is_number(value):
            self.values[key] = math.radians(value)
        elif isinstance(value, list) and all(is_number(v) for v in value):
            self.values[key] = [math.radians(v) for v in value]
        else:
            self.fail(deg_key, value, "a number or a list of numbers (degrees)")
        self.degrees[key] = value

    def fail(self, key: str, value: Any, rule: str) -> NoReturn:
        """Raise the SpecError for field ``key``, spelled and valued as the user wrote it."""
        if key in self.degrees:
            if is_number(value):
                rule += f" (given in degrees: {value:.6g} rad)"
            key, value = key + "_deg", self.degrees[key]
        fail(key, show(value), self.where, self.source, rule)

    def fail_item(self, key: str, index: int, rule: str) -> NoReturn:
        """Raise the SpecError for entry ``index`` of the list under ``key``, as the user wrote it."""
        spelled, given = (key + "_deg", self.degrees[key]) if key in self.degrees else (key, self.values[key])
        fail(f"{spelled}[{index}]", show(given[index]), self.where, self.source, rule)

    def has(self, key: str) -> bool:
        return key in self.values

    def _absent(self, key: str, default: Any, kind: str) -> Any:
        """The default of a field that is not given; a fault if it is required."""
        if default is REQUIRED:
            self.fail(key, Missing(), f"given: {kind}")
        return default

    def number(self, key: str, rule: Rule = ANY, default: Any = REQUIRED) -> float:
        """A finite number obeying ``rule``; ``default`` if absent (unless required)."""
        if key not in self.values:
            return self._absent(key, default, "a number" if rule is ANY else f"a number {rule.text}")
        value = self.values[key]
        problem = validate.check_number(value, ANY)
        if problem:
            self.fail(key, value, problem)
        if not rule.test(value):
            self.fail(key, value, rule.text)
        return float(value)

    def numbers(self, key: str, rule: Rule = ANY, default: Any = REQUIRED) -> tuple[float, ...]:
        """A list of finite numbers, each obeying ``rule``."""
        if key not in self.values:
            return self._absent(key, default, "a list of numbers")
        value = self.values[key]
        if not isinstance(value, list):
            self.fail(key, value, "a list of numbers")
        if len(value) > validate.MAX_TABLE:
            self.fail(key, value, f"a list of at most {validate.MAX_TABLE} numbers (it has {len(value)})")
        for i, item in enumerate(value):
            if not validate.is_finite(item) or not rule.test(item):
                self.fail_item(key, i, "a finite number" if rule is ANY else f"a finite number {rule.text}")
        return tuple(float(item) for item in value)

    def text(self, key: str, default: Any = REQUIRED) -> str:
        """A non-empty string."""
        if key not in self.values:
            return self._absent(key, default, "a non-empty string")
        value = self.values[key]
        if not isinstance(value, str) or not value.strip():
            self.fail(key, value, "a non-empty string")
        return value

    def flag(self, key: str, default: Any = REQUIRED) -> bool:
        """true or false."""
        if key not in self.values:
            return self._absent(key, default, "true or false")
        value = self.values[key]
        if not isinstance(value, bool):
            self.fail(key, value, "true or false")
        return value

    def choice(self, key: str, choices: Iterable[str], default: Any = REQUIRED) -> str:
        """One of ``choices``, matched case-insensitively and returned as spelled there."""
        choices = tuple(choices)
        value = self.values[key] if key in self.values else self._absent(key, default, f"one of {', '.join(choices)}")
        by_lower = {c.lower(): c for c in choices}
        if not isinstance(value, str) or value.lower() not in by_lower:
            self.fail(key, value, f"one of {', '.join(choices)}")
        return by_lower[value.lower()]

    def section(self, key: str, fields: Optional[Iterable[str]], angles: Iterable[str] = (), required: bool = False):
        """The mapping under ``key`` as a Section (an empty one if absent and not required).

        ``fields=None`` leaves the check of its keys to the caller (see check_fields).
        """
        value = self.values.get(key, REQUIRED if required else {})
        if value is REQUIRED:
            self._absent(key, REQUIRED, "a mapping of fields")
        if not isinstance(value, dict):
            self.fail(key, value, "a mapping of fields")
        return Section(value, self._child(key), self.source, fields, angles)

    def sections(self, key: str, fields: Iterable[str], angles: Iterable[str] = (), required: bool = False):
        """The list of mappings under ``key`` as Sections (empty if absent and not required)."""
        value = self.values.get(key, REQUIRED if required else [])
        if value is REQUIRED:
            self._absent(key, REQUIRED, "a non-empty list of mappings")
        if not isinstance(value, list) or (required and not value):
            self.fail(key, value, "a non-empty list of mappings" if required else "a list of mappings")
        for i, item in enumerate(value):
            if not isinstance(item, dict):
                fail(f"{key}[{i}]", show(item), self.where, self.source, "a mapping of fields")
        return [Section(item, f"{self._child(key)}[{i}]", self.source, fields, angles) for i, item in enumerate(value)]

    def _child(self, key: str) -> str:
        return f"{self.path}.{key}" if self.path else key
