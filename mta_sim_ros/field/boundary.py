"""A field: its boundary and obstacles in a local metric frame, read from GeoJSON or YAML.

Two file forms, one ``Field``:

- **GeoJSON** (RFC 7946: WGS84 longitude, latitude in degrees): a Polygon, or a Feature or a
  FeatureCollection of one Feature holding one. Its exterior ring is the boundary, its interior
  rings the obstacles (holes). The Feature's ``properties`` may give ``name``, ``headlands`` (the
  number of headland rings) and ``entry`` ([lon, lat]: where the unit enters the field). The
  field is projected with pyproj to the UTM zone of its centre (WGS 84 / UTM, EPSG 326zz north,
  327zz south) and shifted so that the south-west corner of its bounding box is the origin: x east,
  y north, metres, the frame every plan, run and bag of the field uses (``crs`` and ``origin`` say
  how to go back).
- **YAML** in a local metric frame already: ``boundary: [[x, y], ...]`` (m), ``holes: [[[x, y],
  ...], ...]``, and optionally ``name``, ``headlands``, ``entry: [x, y]``.

Rings run counterclockwise for the boundary and clockwise for holes (RFC 7946, 3.1.6); a ring may
repeat its first point at its end or not. Every field is checked before anything uses it, and a
fault is one line naming the field, the value and the rule (``FieldError``, exit code 2): a
non-finite or out-of-range coordinate, a ring of fewer than 3 distinct points, a ring that
crosses itself or another (shapely's validity), a boundary that runs clockwise (inside-out), a
hole that is not inside the boundary, a field too small to work or too large for one UTM zone.
Geometry is shapely's: no polygon arithmetic is written here.
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from shapely import geometry as sg
from shapely.validation import explain_validity

from .. import validate
from ..validate import InputError

#: bytes of a field file read at most (a hand-drawn or surveyed field has thousands of points)
MAX_FILE_BYTES = 8 << 20
#: vertices of a field, all rings together
MAX_VERTICES = 200_000
#: m^2: the smallest field (one are)
MIN_AREA = 100.0
#: m: the largest extent of a field; farther, one UTM zone's scale error passes ~0.1 %
MAX_EXTENT = 50_000.0
#: headland rings a field may ask for
MAX_HEADLANDS = 20
#: |latitude| UTM covers
MAX_LATITUDE = 84.0
#: |x|, |y| of a local field, m
MAX_LOCAL = 1e7

LOCAL = "local"  # the crs of a field given in a local metric frame
FIELD_KEYS = ("name", "boundary", "holes", "headlands", "entry")


class FieldError(InputError):
    """A field file breaks a rule: one line naming the field, its value, where, and the rule."""


@dataclass(frozen=True)
class Field:
    """A field in its local metric frame (x east, y north, m)."""

    name: str
    polygon: sg.Polygon  # the boundary, counterclockwise, with the obstacles as holes
    headlands: int  # headland rings the plan lays along the boundary (and around each obstacle)
    entry: Optional[tuple[float, float]]  # where the unit enters, or None: the plan chooses
    crs: str  # LOCAL, or the EPSG code of the UTM zone the field was projected to ("EPSG:32633")
    origin: tuple[float, float]  # the local frame's origin in crs (easting, northing); (0, 0) if LOCAL
    source: str  # the file, for messages

    @property
    def area(self) -> float:
        """m^2, holes excluded."""
        return float(self.polygon.area)

    def to_crs(self, xy):
        """Local (x, y) -> coordinates in ``crs`` (easting, northing)."""
        return xy[0] + self.origin[0], xy[1] + self.origin[1]

    def to_wgs84(self, points) -> list[tuple[float, float]]:
        """Local points [(x, y), ...] -> [(lon, lat), ...] (a LOCAL field has no geographic place:
        FieldError)."""
        if self.crs == LOCAL:
            raise FieldError(validate.fault_message("crs", "local", "a projected field (GeoJSON) to be written in WGS84",
                                                    "field", self.source))
        back = _transformer(self.crs, inverse=True)
        xs = [p[0] + self.origin[0] for p in points]
        ys = [p[1] + self.origin[1] for p in points]
        lon, lat = back.transform(xs, ys)
        return list(zip(map(float, lon), map(float, lat)))


# --------------------------------------------------------------------------- reading


def load_field(path) -> Field:
    """The field of a GeoJSON (.geojson, .json) or YAML (.yaml, .yml) file, checked."""
    source = str(path)
    suffix = Path(source).suffix.lower()
    if suffix in (".geojson", ".json"):
        return field_from_geojson(_read_json(path), source)
    if suffix in (".yaml", ".yml"):
        return field_from_yaml(validate.read_mapping(path, FieldError), source)
    _fail("file", validate.show(Path(source).name), "a .geojson, .json, .yaml or .yml field file", "document", source)


def field_from_yaml(data: dict, source: str) -> Field:
    """A field in a local metric frame: ``boundary``, ``holes``, ``name``, ``headlands``, ``entry``."""
    unknown = [k for k in data if k not in FIELD_KEYS]
    if unknown:
        _fail(str(unknown[0]), "unknown", validate.unknown_name_rule(unknown[0], FIELD_KEYS), "top level", source)
    if "boundary" not in data:
        _fail("boundary", "(missing)", "given: the field's outline [[x, y], ...] in m", "top level", source)
    holes = data.get("holes", [])
    if not isinstance(holes, list):
        _fail("holes", validate.show(holes), "a list of rings [[[x, y], ...], ...]", "top level", source)
    outer = _ring(data["boundary"], "boundary", source, MAX_LOCAL, "m")
    inner = [_ring(h, f"holes[{i}]", source, MAX_LOCAL, "m") for i, h in enumerate(holes)]
    entry = None if data.get("entry") is None else _point(data["entry"], "entry", source, MAX_LOCAL, "m")
    return _checked(_name(data, source), outer, inner, _headlands(data, source), entry, LOCAL, (0.0, 0.0), source)


def field_from_geojson(doc: object, source: str) -> Field:
    """A GeoJSON Polygon (bare, in a Feature, or in a FeatureCollection of one Feature) in WGS84,
    projected to its UTM zone (module docstring)."""
    geometry, properties = _polygon_of(doc, source)
    rings = geometry.get("coordinates")
    if not isinstance(rings, list) or not rings:
        _fail("coordinates", validate.show(rings), "a list of linear rings, the boundary first", "geometry", source)
    lonlat = [_ring(r, "boundary" if i == 0 else f"holes[{i - 1}]", source, 180.0, "deg", geographic=True)
              for i, r in enumerate(rings)]
    entry = properties.get("entry")
    entry_lonlat = None if entry is None else _point(entry, "entry", source, 180.0, "deg", geographic=True)
    lon = [p[0] for p in lonlat[0]]
    lat = [p[1] for p in lonlat[0]]
    crs = utm_crs(0.5 * (min(lon) + max(lon)), 0.5 * (min(lat) + max(lat)))
    forward = _transformer(crs)
    projected = []
    for ring in lonlat:
        e, n = forward.transform([p[0] for p in ring], [p[1] for p in ring])
        projected.append([(float(a), float(b)) for a, b in zip(e, n)])
    origin = (min(p[0] for p in projected[0]), min(p[1] for p in projected[0]))
    local = [[(x - origin[0], y - origin[1]) for x, y in ring] for ring in projected]
    entry_xy = None
    if entry_lonlat is not None:
        e, n = forward.transform([entry_lonlat[0]], [entry_lonlat[1]])
        entry_xy = (float(e[0]) - origin[0], float(n[0]) - origin[1])
    return _checked(_name(properties, source, default=Path(source).stem), local[0], local[1:],
                    _headlands(properties, source), entry_xy, crs, origin, source)


def utm_crs(lon: float, lat: float) -> str:
    """The EPSG code of the WGS 84 / UTM zone holding (lon, lat): 326zz north of the equator,
    327zz south, zz = floor((lon + 180) / 6) + 1 (Norway's and Svalbard's exceptions not made)."""
    zone = min(int(math.floor((lon + 180.0) / 6.0)) + 1, 60)
    return f"EPSG:{32600 + zone if lat >= 0.0 else 32700 + zone}"


def _transformer(crs: str, inverse: bool = False):
    from pyproj import Transformer

    pair = (crs, "EPSG:4326") if inverse else ("EPSG:4326", crs)
    return Transformer.from_crs(*pair, always_xy=True)


# --------------------------------------------------------------------------- the checks


def _checked(name, outer, inner, headlands, entry, crs, origin, source) -> Field:
    """The Field of these rings, or FieldError for the first rule they break."""
    if sum(map(len, [outer, *inner])) > MAX_VERTICES:
        _fail("boundary", f"{sum(map(len, [outer, *inner]))} vertices", f"at most {MAX_VERTICES} vertices in all rings",
              "field", source)
    shell = sg.Polygon(outer)
    if not shell.is_valid:
        _fail("boundary", explain_validity(shell), "a simple ring (it may not cross or touch itself)", "field", source)
    if not shell.exterior.is_ccw:
        _fail("boundary", "clockwise (inside-out)", "counterclockwise (RFC 7946: exterior rings run counterclockwise)",
              "field", source)
    width = max(shell.bounds[2] - shell.bounds[0], shell.bounds[3] - shell.bounds[1])
    if width > MAX_EXTENT:
        _fail("boundary", f"{width:.6g} m across", f"at most {MAX_EXTENT:g} m across (one UTM zone's field)", "field",
              source)
    for i, ring in enumerate(inner):
        hole = sg.Polygon(ring)
        if not hole.is_valid:
            _fail(f"holes[{i}]", explain_validity(hole), "a simple ring (it may not cross or touch itself)", "field",
                  source)
        if hole.exterior.is_ccw:
            _fail(f"holes[{i}]", "counterclockwise", "clockwise (RFC 7946: interior rings run clockwise)", "field",
                  source)
        if not shell.contains(hole):
            _fail(f"holes[{i}]", "not inside the boundary", "an obstacle inside the field's boundary", "field", source)
    polygon = sg.Polygon(outer, inner)
    if not polygon.is_valid:
        _fail("holes", explain_validity(polygon), "obstacles that neither cross nor touch each other", "field", source)
    if polygon.area < MIN_AREA:
        _fail("boundary", f"{polygon.area:.4g} m^2 (obstacles taken out)", f"at least {MIN_AREA:g} m^2", "field",
              source)
    if entry is not None and polygon.exterior.distance(sg.Point(entry)) > width:
        _fail("entry", f"{polygon.exterior.distance(sg.Point(entry)):.4g} m from the boundary",
              "near the field: within its width of the boundary", "field", source)
    return Field(name, polygon, headlands, entry, crs, origin, source)


def _ring(value, field: str, source: str, limit: float, unit: str, geographic: bool = False) -> list:
    """A list of [x, y] points (the closing point dropped if repeated), each finite and within
    +-limit (geographic: longitude within +-180, latitude within +-MAX_LATITUDE deg)."""
    if not isinstance(value, list):
        _fail(field, validate.show(value), "a list of points [[x, y], ...]", "field", source)
    points = [_point(p, f"{field}[{i}]", source, limit, unit, geographic) for i, p in enumerate(value)]
    if len(points) > 1 and points[0] == points[-1]:
        points = points[:-1]
    if len(set(points)) < 3:
        _fail(field, f"{len(set(points))} distinct points", "a ring of at least 3 distinct points", "field", source)
    return points


def _point(value, field: str, source: str, limit: float, unit: str, geographic: bool = False) -> tuple[float, float]:
    if not isinstance(value, (list, tuple)) or len(value) not in (2, 3) or not all(map(validate.is_number, value)):
        _fail(field, validate.show(value), "a point [x, y] of two numbers", "field", source)
    x, y = float(value[0]), float(value[1])
    if not (math.isfinite(x) and math.isfinite(y)):
        _fail(field, validate.show(value), "finite", "field", source)
    if geographic:
        if not (abs(x) <= 180.0 and abs(y) <= MAX_LATITUDE):
            _fail(field, validate.show(value), f"[lon, lat] in degrees, |lon| <= 180, |lat| <= {MAX_LATITUDE:g} (UTM)",
                  "field", source)
    elif not (abs(x) <= limit and abs(y) <= limit):
        _fail(field, validate.show(value), f"within +-{limit:g} {unit}", "field", source)
    return x, y


def _name(data: dict, source: str, default: Optional[str] = None) -> str:
    name = data.get("name", default if default is not None else Path(source).stem)
    if not isinstance(name, str) or not 0 < len(name) <= 100 or not name.isprintable():
        _fail("name", validate.show(name), "1 to 100 printable characters", "top level", source)
    return name


def default_folder(parent: str, field: "Field", flag: str = "--out") -> Path:
    """parent/<the field's name>, the folder a command writes into when ``flag`` is not given; a name
    that cannot name one folder there (a / or \\, . or ..) is refused: give ``flag``."""
    name = field.name
    if any(c in name for c in "/\\") or name in (".", ".."):
        _fail(flag, "(not given)", f"given: the field's name {validate.show(name)} cannot name the default folder "
              f"{parent}/<name> (it holds / or \\, or is . or ..)", "command line", field.source)
    return Path(parent) / name


def _headlands(data: dict, source: str) -> int:
    value = data.get("headlands", 1)
    if not (validate.is_number(value) and float(value).is_integer() and 0 <= value <= MAX_HEADLANDS):
        _fail("headlands", validate.show(value), f"an integer in [0, {MAX_HEADLANDS}]", "top level", source)
    return int(value)


def _polygon_of(doc: object, source: str) -> tuple[dict, dict]:
    """(the Polygon geometry, the Feature's properties) of a GeoJSON document."""
    if not isinstance(doc, dict):
        _fail("file", f"a {type(doc).__name__}", "a GeoJSON object", "document", source)
    kind = doc.get("type")
    if kind == "FeatureCollection":
        features = doc.get("features")
        if not isinstance(features, list) or len(features) != 1:
            shown = f"{len(features)} features" if isinstance(features, list) else validate.show(features)
            _fail("features", shown, "one Feature: one field a file", "FeatureCollection", source)
        return _polygon_of(features[0], source)
    if kind == "Feature":
        properties = doc.get("properties") or {}
        if not isinstance(properties, dict):
            _fail("properties", validate.show(properties), "a mapping or null", "Feature", source)
        geometry, _ = _polygon_of(doc.get("geometry"), source)
        return geometry, properties
    if kind != "Polygon":
        _fail("type", validate.show(kind), "Polygon, or a Feature or FeatureCollection of one (one field a file)",
              "geometry", source)
    return doc, {}


def _read_json(path) -> object:
    source = str(path)
    data = validate.read_limited(path, MAX_FILE_BYTES, "UTF-8 GeoJSON field file", FieldError)

    def refuse(constant):  # JSON has no NaN or Infinity; Python's reader would take them
        _fail("coordinates", constant, "finite (JSON numbers)", "document", source)

    try:
        return json.loads(data.decode("utf-8"), parse_constant=refuse)
    except (UnicodeDecodeError, json.JSONDecodeError) as err:
        _fail("file", f"not JSON ({err})", "a GeoJSON file (RFC 7946)", "document", source)
    except RecursionError:
        _fail("file", "nested too deeply", "a GeoJSON file (RFC 7946)", "document", source)


def _fail(field: str, value: str, rule: str, where: str, source: str):
    validate.fail(field, value, rule, where, os.fspath(source), FieldError)
