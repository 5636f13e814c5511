"""``mta field plan`` and a plan's files: the example fields plan, every hostile field is refused
in one line naming it (exit 2, nothing written), the files written read back as the route planned
(CSV and bag), and routes exported by other planners (a nav_msgs/Path in a bag, a CSV of x, y)
are read, or refused in one line."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from mta_sim_ros.bag import BagWriter
from mta_sim_ros.bag.writer import header, yaw_quaternion
from mta_sim_ros.field.boundary import load_field
from mta_sim_ros.field.plan import plan_field
from mta_sim_ros.field.plan_io import PLAN_TYPE, geojson_document, route_csv, write_bag
from mta_sim_ros.field.route_io import read_route
from mta_sim_ros.field.types import PlanOptions
from mta_sim_ros.physics.loader import load_train

from fieldcli import field_command, field_refused

DEFAULT = load_train("config/trains/default.yaml")
ROUTE_ARRAYS = ("xy", "s", "heading", "curvature", "working", "reverse", "segment")


def run(capsys, *args) -> tuple[int, str, str]:
    return field_command(capsys, "plan", *args)


def refused(capsys, expected: tuple, *args) -> str:
    return field_refused(capsys, expected, "plan", *args)


@pytest.mark.parametrize("name", ["rectangle.yaml", "irregular.yaml", "kuban.geojson"])
def test_the_example_fields_plan(capsys, tmp_path, name):
    code, out, err = run(capsys, f"fields/{name}", "--out", tmp_path)
    assert code == 0, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plan.csv", "plan.geojson", "plan.mcap"]
    for word in ("swaths", "turns", "headland", "turn radius", "route", "target"):
        assert word in out
    field = load_field(f"config/fields/{name}")
    back = read_route(tmp_path / "plan.mcap", field)
    assert not back.inferred and back.route.working.any()


YAML_FAULTS = {
    "self_intersecting": ("boundary: [[0, 0], [100, 100], [100, 0], [0, 100]]", "a simple ring"),
    "empty": ("boundary: []", "at least 3 distinct points"),
    "inside_out": ("boundary: [[0, 0], [0, 100], [100, 100], [100, 0]]", "clockwise"),
    "tiny": ("boundary: [[0, 0], [5, 0], [5, 5], [0, 5]]", "at least 100 m^2"),
    "huge": ("boundary: [[0, 0], [60000, 0], [60000, 60000], [0, 60000]]", "at most 50000 m across"),
    "non_finite": ("boundary: [[0, 0], [.nan, 0], [100, 100], [0, 100]]", "finite"),
    "infinite": ("boundary: [[0, 0], [.inf, 0], [100, 100], [0, 100]]", "finite"),
    "hole_outside": ("boundary: [[0, 0], [100, 0], [100, 100], [0, 100]]\nholes: [[[200, 200], [200, 210], "
                     "[210, 210], [210, 200]]]", "inside the field's boundary"),
    "too_many_headlands": ("boundary: [[0, 0], [100, 0], [100, 30], [0, 30]]\nheadlands: 3",
                           "few and tight enough to leave ground inside them"),
    "too_large_a_route": ("boundary: [[0, 0], [20000, 0], [20000, 20000], [0, 20000]]", "vertices"),
}
POLYGON = [[39.0, 45.0], [39.01, 45.0], [39.01, 45.01], [39.0, 45.01], [39.0, 45.0]]
JSON_FAULTS = {
    "nan_in_json": ('{"type": "Polygon", "coordinates": [[[39.0, 45.0], [NaN, 45.0], [39.01, 45.01], [39.0, 45.0]]]}',
                    "finite (JSON numbers)"),
    "multipolygon": (json.dumps({"type": "MultiPolygon", "coordinates": [[POLYGON]]}), "Polygon"),
    "two_fields": (json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {}, "geometry": {"type": "Polygon", "coordinates": [POLYGON]}}] * 2}),
        "one Feature"),
}


@pytest.mark.parametrize("case", sorted(YAML_FAULTS) + sorted(JSON_FAULTS))
def test_a_hostile_field_is_refused_in_one_line_naming_it(capsys, tmp_path, case):
    text, rule = YAML_FAULTS.get(case) or JSON_FAULTS[case]
    path = tmp_path / (f"{case}.yaml" if case in YAML_FAULTS else f"{case}.geojson")
    path.write_text(text)
    out = tmp_path / "out"
    line = refused(capsys, (rule, path.name), path, "--out", out)
    assert line.startswith("mta field plan: ")
    assert not out.exists() or not any(out.iterdir())


def test_a_train_without_an_implement_and_bad_options_are_refused(capsys, tmp_path):
    out = tmp_path / "out"
    refused(capsys, ("implement", "single_tractor"), "fields/rectangle.yaml", "--train", "trains/single_tractor.yaml",
            "--out", out)
    refused(capsys, ("--overlap", "0.6"), "fields/rectangle.yaml", "--overlap", "0.6", "--out", out)
    refused(capsys, ("--angle", "nan"), "fields/rectangle.yaml", "--angle", "nan", "--out", out)
    refused(capsys, ("--route",), "fields/rectangle.yaml", "--route", "spiral", "--out", out)
    assert not out.exists() or not any(out.iterdir())


def test_no_output_overwrites_an_input(capsys, tmp_path):
    field = tmp_path / "plan.geojson"
    field.write_text(open("config/fields/kuban.geojson").read())
    before = field.read_bytes()
    refused(capsys, ("--out", "plan.geojson"), field, "--out", tmp_path)
    assert field.read_bytes() == before and sorted(p.name for p in tmp_path.iterdir()) == ["plan.geojson"]


# --------------------------------------------------------------------------- the files of a plan


@pytest.fixture(scope="module")
def kuban_plan():
    field = load_field("config/fields/kuban.geojson")
    return plan_field(field, DEFAULT, PlanOptions(width=12.0, overlap=0.15, turn="fishtail"))


def same_route(a, b) -> None:
    for name in ROUTE_ARRAYS:
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_a_plan_reads_back_from_its_csv_and_its_bag(kuban_plan, tmp_path):
    plan = kuban_plan
    assert plan.route.reverse.any()  # a fishtail is in it: the reversed flags travel too
    (tmp_path / "plan.csv").write_text(route_csv(plan))
    write_bag(plan, tmp_path / "plan.mcap")
    for name in ("plan.csv", "plan.mcap"):
        back = read_route(tmp_path / name, plan.field)
        same_route(back.route, plan.route)
        assert back.route.spacing == plan.route.spacing
        assert back.segments == plan.segments and not back.inferred


def test_the_bags_path_is_the_route_with_its_carts_heading(kuban_plan, tmp_path):
    from mta_sim_ros.bag import read_messages, summary

    write_bag(kuban_plan, tmp_path / "plan.mcap")
    assert summary(tmp_path / "plan.mcap") == {"/plan": {"type": PLAN_TYPE, "count": 1}}
    (_, _, path), = list(read_messages(tmp_path / "plan.mcap"))
    route = kuban_plan.route
    assert path.header.frame_id == "map" and len(path.poses) == len(route.s)
    xy = np.array([[p.pose.position.x, p.pose.position.y] for p in path.poses])
    yaw = np.array([2 * math.atan2(p.pose.orientation.z, p.pose.orientation.w) for p in path.poses])
    assert np.array_equal(xy, route.xy)
    cart = route.heading + np.where(route.reverse, math.pi, 0.0)
    assert np.abs(np.remainder(yaw - cart + math.pi, 2 * math.pi) - math.pi).max() < 1e-12


def test_geojson_is_wgs84_for_a_placed_field_and_says_its_frame_otherwise(kuban_plan):
    doc = geojson_document(kuban_plan)
    kinds = {f["properties"]["kind"] for f in doc["features"]}
    assert kinds == {"boundary", "inner", "headland", "swath", "turn", "transit"}
    source = json.load(open("config/fields/kuban.geojson"))["features"][0]["geometry"]["coordinates"][0]
    boundary = doc["features"][0]["geometry"]["coordinates"][0]
    start = min(range(len(boundary)), key=lambda i: math.dist(boundary[i], source[0]))
    assert math.dist(boundary[start], source[0]) < 1e-8  # projected and back: the same place
    assert "mta_frame" not in doc
    local = plan_field(load_field("config/fields/rectangle.yaml"), DEFAULT, PlanOptions(width=12.0, angle=0.0))
    doc = geojson_document(local)
    assert "local metric" in doc["mta_frame"]
    assert [0.0, 0.0] in doc["features"][0]["geometry"]["coordinates"][0]


# --------------------------------------------------------------------------- foreign routes


def u_route(radius=10.0, length=100.0, step=1.0):
    """A straight pass, a U of ``radius`` and a pass back, as a planner's points."""
    out = [(x, 0.0) for x in np.arange(0.0, length, step)]
    out += [(length + radius * math.sin(a), radius - radius * math.cos(a)) for a in np.linspace(0, math.pi, 40)]
    out += [(x, 2 * radius) for x in np.arange(length - step, -step / 2, -step)]
    return np.array(out)


def kinds(back) -> list[str]:
    return [s.kind for s in back.segments]


@pytest.mark.parametrize("with_header", [True, False])
def test_a_csv_of_points_is_read_with_its_turns_inferred(tmp_path, with_header):
    points = u_route()
    path = tmp_path / "f2c.csv"
    rows = "".join(f"{float(x)!r},{float(y)!r}\n" for x, y in points)
    path.write_text(("x,y\n" if with_header else "") + rows)
    back = read_route(path)
    assert back.inferred and kinds(back) == ["swath", "turn", "swath"]
    assert (back.segments[1].first, back.segments[1].last) == (100, 139)  # the arc's first and last points
    assert np.array_equal(back.route.xy, points)
    turn = back.segments[1]
    assert np.abs(back.route.curvature[turn.first + 1:turn.last]) == pytest.approx(0.1, rel=2e-3)


def path_bag(path, points, yaw, topic="/coverage_server/coverage_plan"):
    poses = [{"header": header(0.0, "map"), "pose": {"position": {"x": float(x), "y": float(y), "z": 0.0},
                                                      "orientation": yaw_quaternion(float(h))}}
             for (x, y), h in zip(points, yaw)]
    with BagWriter(path) as bag:
        bag.add_topic(topic, PLAN_TYPE)
        bag.write(topic, {"header": header(0.0, "map"), "poses": poses}, log_time_ns=0)


def test_a_foreign_path_in_a_bag_is_read_and_poses_facing_back_are_reversing(tmp_path):
    points = u_route()
    heading = np.arctan2(*np.diff(points, axis=0)[:, ::-1].T)
    yaw = np.concatenate([heading, heading[-1:]])
    yaw[-20:] += math.pi  # the last 20 m backed up: the poses point against the motion
    path_bag(tmp_path / "nav2.mcap", points, yaw)
    back = read_route(tmp_path / "nav2.mcap")
    assert kinds(back) == ["swath", "turn", "swath", "turn"]
    assert back.segments[-1].reverse and not back.segments[0].reverse
    assert back.route.reverse[-19:].all() and not back.route.reverse[:-20].any()


ROUTE_FAULTS = {
    "nan": ("x,y\n0,0\nnan,1\n2,2\n", "finite"),
    "one_point": ("x,y\n3,4\n3,4\n", "at least 2 distinct points"),
    "words": ("x,y\n0,0\n1,one\n", "a number"),
    "no_y": ("x,z\n0,0\n1,1\n", "columns x and y"),
    "far": ("x,y\n0,0\n100,0\n90000,0\n", "across"),
    "outside_field": ("x,y\n0,0\n100,0\n1000,0\n", "within the field's extent"),
    "empty": ("# nothing\n", "at least 2 points"),
}


@pytest.mark.parametrize("case", sorted(ROUTE_FAULTS))
def test_a_bad_foreign_route_is_refused_in_one_line(tmp_path, case):
    from mta_sim_ros.field.boundary import FieldError

    text, rule = ROUTE_FAULTS[case]
    path = tmp_path / f"{case}.csv"
    path.write_text(text)
    field = load_field("config/fields/rectangle.yaml")
    with pytest.raises(FieldError) as err:
        read_route(path, field)
    message = str(err.value)
    assert "\n" not in message and rule in message and path.name in message, message


def test_a_bag_with_no_path_is_refused(tmp_path):
    from mta_sim_ros.field.boundary import FieldError

    with BagWriter(tmp_path / "other.mcap") as bag:
        bag.add_topic("/x", "std_msgs/msg/Float64")
        bag.write("/x", {"data": 1.0}, log_time_ns=0)
    with pytest.raises(FieldError, match="a topic of nav_msgs/msg/Path"):
        read_route(tmp_path / "other.mcap")
