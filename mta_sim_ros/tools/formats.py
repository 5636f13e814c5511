"""docs/formats.md, the reference of the train, scene and sweep spec files, written from the rules
the readers apply: ``python -m mta_sim_ros.tools.formats > docs/formats.md`` (or ``--out FILE``).

The train and scene sections come from the loader's declarations (physics/schema.py: every field's
kind, unit, rule, default and meaning; the named manoeuvres from physics/maneuvers.py), the
bounds from validate.py. The sweep spec's rules are code in sweep/spec.py, not declarations: its
section is written here by hand, with its field lists, choices and bounds read from that module's
constants, and fails to generate when the spec gains a field this page does not describe.
test/test_docs.py holds docs/formats.md to this output.
"""
from __future__ import annotations

import argparse
import inspect
import math
import re
import sys

from .. import validate
from ..physics import maneuvers, schema
from ..physics.reader import REQUIRED
from ..physics.schema import CHOICE, FLAG, MAPPING, MAPPINGS, NUMBER, NUMBERS, SPEED_COMMAND, TEXT, Field, Schema
from ..sweep import spec as sweep_spec

COMMAND = "python -m mta_sim_ros.tools.formats > docs/formats.md"


def slug(heading: str) -> str:
    """The anchor GitHub gives a heading."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def heading(s: Schema) -> str:
    return f"{s.title} (`{s.where}`)"


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def _value(value) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float):
        return "no limit" if math.isinf(value) else f"{value:g}"
    if value in ((), {}, None):
        return "none"
    return str(value)


def _default(f: Field) -> str:
    if f.default_text:
        return f.default_text
    return "**required**" if f.default is REQUIRED else _value(f.default)


def _kind(f: Field) -> str:
    if f.kind in (MAPPING, MAPPINGS, SPEED_COMMAND) and f.schema is not None:
        return f"[{f.kind}](#{slug(heading(f.schema))})"
    return f.kind


def _rule(f: Field) -> str:
    if f.kind in (NUMBER, NUMBERS, SPEED_COMMAND):
        words = f.rule_text or (f.rule.text if f.rule is not None and f.rule is not validate.ANY else "finite")
        words = ("each " if f.kind == NUMBERS else "") + words
    elif f.kind == CHOICE:
        words = "one of " + ", ".join(f.choices)
    elif f.kind == TEXT:
        words = "a non-empty string" + (f": {f.rule_text}" if f.rule_text else "")
    elif f.kind == FLAG:
        words = "true or false"
    else:
        words = ""
    return "; ".join(w for w in (words, f.also) if w)


def field_rows(s: Schema) -> list[str]:
    rows = ["| field | type | unit | rule | default | meaning |", "|---|---|---|---|---|---|"]
    for f in s.fields:
        key = f"`{f.key}` or `{f.key}_deg`" if f.angle else f"`{f.key}`"
        cells = (key, _kind(f), f.unit, _rule(f), _default(f), f.meaning)
        rows.append("| " + " | ".join(_cell(c) for c in cells) + " |")
    return rows


def schema_section(s: Schema) -> list[str]:
    lines = ["", f"### {heading(s)}", "", s.meaning, "", *field_rows(s)]
    if s.notes:
        lines += ["", "Also: " + "; ".join(s.notes) + "."]
    return lines


def maneuver_rows() -> list[str]:
    rows = ["| maneuver | params (default; angles also as NAME_deg) | what it does |", "|---|---|---|"]
    for name, m in maneuvers.MANEUVERS.items():
        params = ", ".join(f"`{k}` ({'from the scene' if v is None else _value(float(v))}"
                           f"{' rad' if k in m.angles else ''})" for k, v in m.defaults.items())
        doc = " ".join(inspect.getdoc(m.build).split("\n\n")[0].split())
        doc = re.sub(r":func:`(\w+)`", r"`\1`", doc).replace("``", "`")
        rows.append(f"| `{name}` | {_cell(params) or 'none'} | {_cell(doc)} |")
    return rows


def general() -> list[str]:
    v = validate
    return [
        "## Rules for every file", "",
        "- Units are SI. Angles are in radians, or in degrees under the same key with `_deg` appended "
        "(`max_angle_deg: 40`); giving both forms is a fault.",
        "- Numbers may be ints or floats (`1e-8` is read as a float, unlike plain YAML 1.1) and must be finite.",
        "- A key that is not a field of its mapping is a fault (the message names the closest field); a key given "
        "twice is a fault. A choice (`law: Governor`, `method: rk4`) is matched ignoring case.",
        "- A fault is one line, `FIELD: VALUE in LOCATION of FILE must be RULE`, e.g. "
        "`mass: -3 in carts[1] of trains/x.yaml must be > 0 and <= 1e+07 kg`; LOCATION is a path into the file "
        "(`top level`, `carts[1]` with 0-based indices, `forces.traction`). `mta check FILE...` checks files "
        f"without running them; a command refusing a file exits with code {v.EXIT_INPUT}.",
        f"- A document has at most {v.MAX_YAML_CHARS} characters, {v.MAX_YAML_DEPTH} levels of nesting, "
        f"{v.MAX_YAML_ALIASES} aliases and {v.MAX_YAML_NODES} values with its aliases expanded; a table at most "
        f"{v.MAX_TABLE} entries; a run at most {v.MAX_TICKS:.0e} ticks, {v.MAX_STEPS_PER_TICK} integrator steps a "
        f"tick and {v.MAX_RUN_STEPS:.0e} a run.",
    ]


def sweep_section() -> list[str]:
    """The sweep spec, by hand from sweep/spec.py (its rules are code): refuses to write a page
    that misses one of the spec's fields."""
    sp = sweep_spec
    top = {
        "name": ("string", "the file's stem", "at most 100 ASCII letters (A-Z, a-z), digits, '_', '-' or '.'; "
                 "names the results folder sweeps/<name>/"),
        "train": ("string", "**required**", "the base train file, relative to the spec; it must load"),
        "scenes": ("list of strings", "**required**", f"1 to {sp.MAX_SCENES} scene files, relative to the spec: "
                   "manoeuvre scenes, or field scenes (a field worked whole: [Field scene file](#field-scene-file)); "
                   "each must load (a manoeuvre scene with the train it names) and their names differ"),
        "fidelity": ("choice", "dynamic", "one of " + ", ".join(sp.FIDELITY) + ": the level of every run (one "
                     "level for all schemes, so their metrics compare)"),
        "sample": ("mapping", "method grid", "how schemes are drawn: `method` one of " + ", ".join(sp.METHODS) +
                   f" (default grid); `count` a whole number {sp.COUNT.text}, required for random and saltelli "
                   "(a power of 2 for saltelli: count (2 D + 2) schemes for D factors), left out for grid; `seed` "
                   f"a whole number {sp.SEED.text} (default 0)"),
        "vary": ("list of mappings", "**required**", "the factors, below; not empty"),
        "constraints": ("list of mappings", "none", "`{quantity, min, max}`: quantity one of " +
                        ", ".join(sp.QUANTITIES) + "; at least one of min and max, max >= min; a scheme that "
                        "breaks one is dropped before it runs"),
        "bags": ("list of integers", "none", "at most 1000 run indices in [0, runs - 1]: runs that also write a "
                 "bag"),
        "batch": ("number", "16", f"a whole number {sp.BATCH.text}: runs per task"),
    }
    missing = [key for key in sp.SPEC_FIELDS if key not in top]
    if missing:
        raise SystemExit(f"formats: sweep spec fields {missing} are not described in {__name__}")
    factor = {
        "path": "a field path such as `carts[2].hitch_offset`, `forces.draft[0].width`, "
                "`steering_actuator.time_constant` (of the base train), `scene.speed`, `scene.initial.speed` or a "
                "field scene's `scene.plan.angle_deg` (set in every scene that has the field, at least one), or "
                "`train` (a choice among train files); at most 200 characters; the field must be in the base file",
        "values": "a list of 1 to 100000 numbers (not with low, high, steps)",
        "low, high": "a range, high >= low",
        "steps": f"grid only: a whole number {sp.STEPS.text} of points, ends included (1 when low = high); "
                 "random and saltelli sample the range",
        "choices": "a list of 1 to 1000 values of any kind (for path `train`: train files), not with values, "
                   "low, high, steps",
        "order": "`carts`, alone: every order of the 2 to 8 carts behind the tractor",
    }
    lines = ["", "## Sweep spec", "",
             "A sweep's spec (`mta sweep SPEC`, [sweeps.md](sweeps.md); `config/sweeps/hitching.yaml` is the "
             "worked example). Its rules are code in `mta_sim_ros/sweep/spec.py`, so this section is written by "
             "hand in the generator, its choices and bounds read from that module; the generator stops when the "
             "spec gains a field this section does not describe. Faults are one line, as above.", "",
             "| field | type | default | rule and meaning |", "|---|---|---|---|"]
    lines += [f"| `{k}` | {kind} | {default} | {_cell(words)} |" for k, (kind, default, words) in top.items()]
    lines += ["", "### A factor (`vary[i]`)", "",
              "One thing that varies; a scheme is one value of each factor. Each factor is varied once.", "",
              "| field | rule and meaning |", "|---|---|"]
    lines += [f"| `{k}` | {_cell(words)} |" for k, words in factor.items()]
    lines += ["", f"At most {sp.MAX_SCHEMES} schemes and {sp.MAX_RUNS} runs (schemes x scenes). Before anything "
              "runs, each factor at each end of its range (the others at their first value) must load as a train "
              "and as scenes by the rules above: a range that leaves a field's rule is refused, naming the factor."]
    return lines


#: each field file key, in words (boundary.FIELD_KEYS: a key without words here fails the page)
FIELD_KEYS = {
    "name": "the field's name (default: the file's stem; GeoJSON: the Feature's `name` property)",
    "boundary": "the outline: a ring of [x, y] points in m (GeoJSON: the Polygon's exterior ring of [lon, lat] "
                "in degrees, WGS84), counterclockwise, at least 3 distinct points, not crossing itself",
    "holes": "the obstacles: rings inside the boundary, clockwise, neither crossing nor touching each other "
             "(GeoJSON: the Polygon's interior rings)",
    "headlands": "headland rings along the boundary and round each obstacle",
    "entry": "where the unit enters: [x, y] m (GeoJSON: [lon, lat]), near the field",
}


def field_section() -> list[str]:
    """The field file, by hand from field/boundary.py (its rules are code), and the field scene
    from its declarations (field/scene.py)."""
    from ..field import boundary, scene

    missing = [k for k in boundary.FIELD_KEYS if k not in FIELD_KEYS]
    if missing:
        raise SystemExit(f"formats: field file keys {missing} are not described in {__name__}")
    lines = ["", "## Field file", "",
             "`config/fields/*`: a field's boundary and obstacles, read by `mta_sim_ros/field/boundary.py` "
             "(`mta field plan|run`, a field scene). Two forms: GeoJSON (RFC 7946: WGS84 longitude, latitude in "
             "degrees; a Polygon, or a Feature or a FeatureCollection of one Feature holding one; its properties "
             "give name, headlands and entry), projected with pyproj to the UTM zone of the field's centre and "
             "shifted so that the south-west corner of its bounding box is the origin (x east, y north, m); or "
             "YAML in a local metric frame already, e.g. [config/fields/rectangle.yaml]"
             "(../config/fields/rectangle.yaml).", "",
             "| key | meaning | rule |", "|---|---|---|"]
    rules = {"headlands": f"a whole number in [0, {boundary.MAX_HEADLANDS}], default 1",
             "boundary": f"|x|, |y| <= {boundary.MAX_LOCAL:g} m (GeoJSON: |lon| <= 180, |lat| <= "
                         f"{boundary.MAX_LATITUDE:g} deg); at most {boundary.MAX_EXTENT:g} m across; at least "
                         f"{boundary.MIN_AREA:g} m^2 with the obstacles taken out; at most {boundary.MAX_VERTICES} "
                         "vertices in all rings",
             "entry": "within the field's width of its boundary", "holes": "inside the boundary",
             "name": "1 to 100 printable characters (one with / or \\, or . or .., names no default folder: give --out)"}
    lines += [f"| `{k}` | {_cell(FIELD_KEYS[k])} | {_cell(rules.get(k, ''))} |" for k in boundary.FIELD_KEYS]
    lines += ["", f"A file is at most {boundary.MAX_FILE_BYTES} bytes; JSON's NaN and Infinity are refused.",
              "", "## Field scene file", "", "`config/fieldwork/*.yaml`: a field and how it is worked, e.g. "
              "[config/fieldwork/irregular.yaml](../config/fieldwork/irregular.yaml) (`mta field run`, a sweep's "
              "scenes)."]
    for s in (scene.FIELD_SCENE, scene.PLAN, scene.DRIVE):
        lines += schema_section(s)
    return lines


def markdown() -> str:
    """The whole of docs/formats.md."""
    lines = ["# File formats: train, scene, field, field scene and sweep spec", "",
             f"<!-- Generated: `{COMMAND}`. Do not edit; test/test_docs.py holds this page to the generator. -->",
             "",
             "Every field of the files the simulator reads, with its unit, rule and default. The train and scene "
             "tables are written from the declarations the loader reads every field through "
             "(`mta_sim_ros/physics/schema.py`), so they say what the loader checks. The shipped files are in "
             "[config.md](config.md); the bag a run writes is in [bag.md](bag.md).", ""]
    lines += general()
    lines += ["", "## Train file", "", "`config/trains/*.yaml`, e.g. "
              "[config/trains/default.yaml](../config/trains/default.yaml)."]
    for s in schema.TRAIN_SCHEMAS:
        lines += schema_section(s)
    lines += ["", "## Scene file", "", "`config/scenes/*.yaml`, e.g. "
              "[config/scenes/headland_turn.yaml](../config/scenes/headland_turn.yaml)."]
    for s in schema.SCENE_SCHEMAS:
        lines += schema_section(s)
        if s is schema.MANEUVER_PARAMS:
            lines += ["", "### Named manoeuvres", "", "`steering: {maneuver: NAME, params: {...}}`; from "
                      "`mta_sim_ros/physics/maneuvers.py`. Positive steering turns left.", "", *maneuver_rows()]
    lines += field_section()
    lines += sweep_section()
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m mta_sim_ros.tools.formats", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", help="write here instead of stdout")
    args = parser.parse_args(argv)
    text = markdown()
    if args.out:
        with open(args.out, "w", encoding="utf-8") as stream:
            stream.write(text)
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
