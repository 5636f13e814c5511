"""A plan written out: GeoJSON (the field, its headland rings, swaths and route), CSV (the route's
arrays) and an MCAP bag with one nav_msgs/Path (what Nav2 and opennav_coverage pass on), no ROS.

- **GeoJSON** (RFC 7946): a FeatureCollection in WGS84 longitude, latitude when the field has a
  place (a GeoJSON field, projected back with pyproj); a field given in a local metric frame is
  written in that frame, as the collection's ``mta_frame`` member says (RFC 7946 readers will take
  the numbers for degrees). Features, each with ``kind``: ``boundary`` (Polygon with the obstacles
  as holes), ``inner`` (the swaths' ground), ``headland`` (a ring's centre line, ``index``: its
  place in Plan.headland_rings, ``ring``: its pass number), ``swath`` (``index``: the order
  driven) and the route: one LineString a segment, ``kind`` swath | headland | turn | transit,
  ``segment``, ``index``, ``reverse``, ``working``.
- **CSV**: comment lines (``#``) saying the field and frame, a header, and one row a route vertex:
  ``x, y, s, heading, curvature, working, reverse, segment, kind, index`` (the last two the
  segment's, so the plan's segments can be read back); numbers as Python's shortest exact repr, so
  a route read back is the route written.
- **MCAP**: topic PLAN_TOPIC, one nav_msgs/Path in frame_id ``map`` at log time 0 (QoS transient
  local, as a plan is latched), a pose a vertex: the working point and the way its cart points
  (against the motion where driven backwards); and a metadata record PLAN_METADATA holding the
  route's CSV, from which ``route_io`` reads its flags back (a Path carries none).
"""
from __future__ import annotations

import io
import json
import math

import numpy as np
from shapely import geometry as sg
from shapely.geometry.polygon import orient

from ..bag import BagWriter, header, qos_profiles_yaml
from ..bag.writer import yaw_quaternion
from .boundary import LOCAL
from .headlands import polygons
from .types import Plan

PLAN_TOPIC = "/plan"
PLAN_TYPE = "nav_msgs/msg/Path"
PLAN_METADATA = "mta_sim_ros_plan"
FRAME_ID = "map"
SPACING_LINE = "# spacing_m: "  # the comment line giving the route's vertex spacing
PLAN_LINE = "# mta_sim_ros coverage plan of field "  # the first line of a plan's CSV, the field's name after it
CSV_COLUMNS = ("x", "y", "s", "heading", "curvature", "working", "reverse", "segment", "kind", "index")


def _num(x) -> str:
    return repr(float(x))


def route_csv(plan: Plan) -> str:
    """The route as CSV text (module docstring)."""
    route, field = plan.route, plan.field
    out = io.StringIO()
    out.write(f"{PLAN_LINE}{field.name} ({field.source}); frame: "
              + ("local metric (x east, y north, m)" if field.crs == LOCAL else
                 f"{field.crs} shifted by origin {field.origin[0]!r}, {field.origin[1]!r} (m)") + "\n")
    out.write("# the implement's working point; heading rad (direction of motion), curvature 1/m\n")
    out.write(f"{SPACING_LINE}{route.spacing!r}\n")
    out.write(",".join(CSV_COLUMNS) + "\n")
    kinds = [plan.segments[j].kind for j in range(len(plan.segments))]
    indices = [plan.segments[j].index for j in range(len(plan.segments))]
    for i in range(len(route.s)):
        j = int(route.segment[i])
        out.write(f"{_num(route.xy[i, 0])},{_num(route.xy[i, 1])},{_num(route.s[i])},{_num(route.heading[i])},"
                  f"{_num(route.curvature[i])},{int(route.working[i])},{int(route.reverse[i])},{j},{kinds[j]},"
                  f"{indices[j]}\n")
    return out.getvalue()


# --------------------------------------------------------------------------- GeoJSON


def _coords(plan: Plan, xy) -> list:
    """Points of the field's local frame as GeoJSON positions: [lon, lat] when it has a place."""
    points = [(float(x), float(y)) for x, y in xy]
    if plan.field.crs == LOCAL:
        return [[round(x, 6), round(y, 6)] for x, y in points]
    return [[round(lon, 9), round(lat, 9)] for lon, lat in plan.field.to_wgs84(points)]


def _polygon(plan: Plan, polygon: sg.Polygon) -> list:
    polygon = orient(polygon, 1.0)  # RFC 7946: exteriors counterclockwise, holes clockwise
    return [_coords(plan, polygon.exterior.coords), *(_coords(plan, r.coords) for r in polygon.interiors)]


def _feature(geometry: dict, **properties) -> dict:
    return {"type": "Feature", "properties": properties, "geometry": geometry}


def geojson_document(plan: Plan) -> dict:
    """The plan as a GeoJSON FeatureCollection (module docstring)."""
    field = plan.field
    features = [_feature({"type": "Polygon", "coordinates": _polygon(plan, field.polygon)}, kind="boundary",
                         name=field.name)]
    inner = polygons(plan.inner)
    features.append(_feature({"type": "MultiPolygon", "coordinates": [_polygon(plan, p) for p in inner]},
                             kind="inner"))
    ring_index = _ring_numbers(plan)
    for j, line in enumerate(plan.headland_rings):
        features.append(_feature({"type": "LineString", "coordinates": _coords(plan, line.coords)}, kind="headland",
                                 index=j, ring=ring_index[j]))
    for j, line in enumerate(plan.swaths):
        features.append(_feature({"type": "LineString", "coordinates": _coords(plan, line.coords)}, kind="swath",
                                 index=j))
    route = plan.route
    for j, seg in enumerate(plan.segments):
        features.append(_feature({"type": "LineString", "coordinates": _coords(plan, route.xy[seg.first:seg.last + 1])},
                                 kind=seg.kind, segment=j, index=seg.index, reverse=seg.reverse,
                                 working=bool(route.working[seg.first])))
    doc = {"type": "FeatureCollection", "name": f"{field.name} coverage plan", "features": features}
    if field.crs == LOCAL:
        doc["mta_frame"] = "local metric frame of the field (x east, y north, m), not WGS84: the field has no place"
    return doc


def _ring_numbers(plan: Plan) -> list[int]:
    """Each headland ring's pass number (0 outermost): its offset from the boundary in widths."""
    width = plan.options.width
    outline = plan.field.polygon.boundary
    return [max(0, round(outline.distance(sg.Point(line.coords[0])) / width - 0.5)) for line in plan.headland_rings]


def geojson_text(plan: Plan) -> str:
    return json.dumps(geojson_document(plan), allow_nan=False) + "\n"


# --------------------------------------------------------------------------- MCAP


def path_message(plan: Plan, frame_id: str = FRAME_ID) -> dict:
    """nav_msgs/Path of the route: a pose a vertex, oriented as the cart points."""
    route = plan.route
    cart = route.heading + np.where(route.reverse, math.pi, 0.0)
    poses = [{"header": header(0.0, frame_id),
              "pose": {"position": {"x": float(x), "y": float(y), "z": 0.0}, "orientation": yaw_quaternion(float(h))}}
             for (x, y), h in zip(route.xy, cart)]
    return {"header": header(0.0, frame_id), "poses": poses}


def plan_metadata(plan: Plan) -> dict[str, str]:
    field, options = plan.field, plan.options
    return {"field": field.name, "field_file": field.source, "crs": field.crs,
            "origin": json.dumps(list(field.origin)),
            "options": json.dumps({k: getattr(options, k) for k in options.__dataclass_fields__}),
            "route_csv": route_csv(plan)}


def write_bag(plan: Plan, path) -> None:
    """The plan's bag (module docstring) at ``path`` (overwritten)."""
    latched = qos_profiles_yaml(durability="transient_local", depth=1)
    with BagWriter(path, metadata={PLAN_METADATA: plan_metadata(plan)}) as bag:
        bag.add_topic(PLAN_TOPIC, PLAN_TYPE, latched)
        bag.write(PLAN_TOPIC, path_message(plan), log_time_ns=0)
