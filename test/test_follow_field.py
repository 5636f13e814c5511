"""A field plan worked live: ``mta follow --field`` against the node in lockstep over DDS (loopback,
this session's domain), measured from the node's bag against the offline run of the same plan,
the latched plan and boundary, and the coverage grid against field/coverage.py; and the inputs it
refuses, in one line, exit 2.

What lockstep gives: the node publishes its outputs after its first tick (run with the scene's
initial commands: steering 0, the set speed, lowered), so the node's k-th hitch_poses is the
offline run's row k + 1; with that shift the working point's path equals the offline one to
rounding (the pose travels as a quaternion, psi_1 and V through joint_states and odom: measured
5e-13 m over the whole field), so the bound on the live error is the offline run's own."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import shapely
from dds import Probe, bags_in, read_bag, start_mta, start_node, stop
from hostile import assert_refused, mta
from shapely import geometry as sg

from mta_sim_ros import cli
from mta_sim_ros.config import resolve_config_path
from mta_sim_ros.controllers.implement.design import Settings
from mta_sim_ros.controllers.implement.drive import run_field
from mta_sim_ros.controllers.implement.live import REFUSED, Follow
from mta_sim_ros.field.coverage import coverage
from mta_sim_ros.field.grid import ONCE, SKIPPED, TWICE
from mta_sim_ros.field.plan import plan_field
from mta_sim_ros.field.scene import load_field_scene
from mta_sim_ros.physics.loader import load_train

TRAIN_FILE = Path(resolve_config_path("trains/default.yaml"))
TRAIN = load_train(TRAIN_FILE)


def small_field(folder: Path) -> Path:
    """A 160 m x 100 m field and its scene (three swaths along x, headlands not worked)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "small.yaml").write_text("name: small\nboundary: [[0, 0], [160, 0], [160, 100], [0, 100]]\n"
                                       "headlands: 2\nentry: [0, 0]\n")
    scene = folder / "small_scene.yaml"
    scene.write_text("name: small_seeding\nfield: small.yaml\nplan: {angle_deg: 0, work_headlands: false}\n")
    return scene


def working_point(msg) -> np.ndarray:
    """W of a hitch_poses: ``offset`` ahead of the implement cart's axle B_m = A_m - l_m e_m."""
    m = TRAIN.cart_index(TRAIN.implement.cart)
    p = msg.poses[m]
    th = 2.0 * math.atan2(p.orientation.z, p.orientation.w)
    reach = TRAIN.implement.offset - TRAIN.carts[m].length
    return np.array([p.position.x + reach * math.cos(th), p.position.y + reach * math.sin(th)])


@pytest.mark.dds
def test_mta_follow_works_a_small_field_live_as_offline(tmp_path, probe: Probe):
    from nav_msgs.msg import OccupancyGrid, Path as PathMsg
    from visualization_msgs.msg import MarkerArray

    from mta_sim_ros.node.ros_msgs import LATCHED_QOS

    scene_file = small_field(tmp_path / "field")
    assert cli.main(["follow", "--field", str(scene_file), "--write-scene", str(tmp_path / "start")]) == 0
    params = tmp_path / "start" / "sim.yaml"
    params.write_text(params.read_text().replace("bag_dir: 'bags'", f"bag_dir: '{tmp_path / 'bags'}'"))
    node = start_node(params, tmp_path / "node.log")
    report = tmp_path / "follow.json"
    try:
        follower = start_mta("follow", "--field", scene_file, "--report", report)
        got = {"/plan": [], "/field_boundary": [], "/coverage": []}
        for topic, kind in (("/plan", PathMsg), ("/field_boundary", MarkerArray), ("/coverage", OccupancyGrid)):
            probe.node.create_subscription(kind, topic, got[topic].append, LATCHED_QOS)
        assert probe.spin_until(lambda: follower.poll() is not None, 300.0), "the controller did not finish"
        out = follower.stdout.read()
        assert follower.returncode == 0, out[-3000:]
        probe.spin_until(lambda: got["/plan"] and got["/field_boundary"], 5.0)
    finally:
        assert stop(node) == 0
    assert got["/plan"] and got["/field_boundary"] and got["/coverage"], {k: len(v) for k, v in got.items()}

    # the offline run of the same plan, controller and model
    scene = load_field_scene(scene_file)
    plan = plan_field(scene.field, TRAIN, scene.options(TRAIN))
    offline = run_field(plan, TRAIN, Settings(**scene.drive))
    assert offline.trace.verdict == "ok"
    [path] = got["/plan"][-1:]
    assert path.header.frame_id == "map" and len(path.poses) == plan.route.xy.shape[0]
    np.testing.assert_array_equal([(p.pose.position.x, p.pose.position.y) for p in path.poses], plan.route.xy)
    boundary = got["/field_boundary"][-1].markers
    assert [m.ns for m in boundary] == ["boundary"]
    assert sg.Polygon([(p.x, p.y) for p in boundary[0].points]).equals(scene.field.polygon)

    # the node's bag, read by rosbags: W live against offline, its error on the working stretches
    [bag] = bags_in(tmp_path / "bags")
    msgs = read_bag(bag)
    W = np.array([working_point(m) for _, m in msgs["/hitch_poses"]])
    lowered = np.array([m.data for _, m in msgs["/implement_lowered"]])
    Wo = offline.trace.implement
    assert W.shape[0] == Wo.shape[0] and lowered.size == W.shape[0] - 1
    shift = np.hypot(*(W[:-1] - Wo[1:W.shape[0]]).T)
    print(f"live W against offline row k + 1: largest {shift.max():.3g} m over {shift.size} ticks")
    assert shift.max() < 1e-6
    worked = shapely.union_all([sg.LineString(plan.route.xy[s.first:s.last + 1]) for s in plan.segments
                                if plan.route.working[s.first]])
    live_error = shapely.distance(worked, shapely.points(W[:-1][lowered]))
    offline_working = np.abs(offline.trace.tracking_error[offline.trace.lowered])
    bound = offline_working.max() + 1e-6
    print(f"W's error on working stretches: live max {live_error.max():.4f} m, offline max {bound:.4f} m")
    assert live_error.max() <= bound
    figures = json.loads(report.read_text())
    assert figures["status"] == "done" and figures["finished"]

    # the coverage grid's worked cells against coverage.py's worked polygon rasterized
    grid = got["/coverage"][-1]
    res, cols, rows = grid.info.resolution, grid.info.width, grid.info.height
    values = np.frombuffer(bytes(np.array(grid.data, dtype=np.int8)), dtype=np.int8).reshape(rows, cols)
    xs = grid.info.origin.position.x + (np.arange(cols) + 0.5) * res
    ys = grid.info.origin.position.y + (np.arange(rows) + 0.5) * res
    cx, cy = np.meshgrid(xs, ys)
    cov = coverage(offline.trace, TRAIN)
    polygon = cov.worked
    expected = shapely.contains_xy(polygon, cx, cy)
    live = (values == ONCE) | (values == TWICE)
    differ = live != expected
    near = shapely.distance(polygon.boundary, shapely.points(cx[differ], cy[differ])) <= res * math.sqrt(0.5)
    print(f"coverage grid: {live.sum()} worked cells, {expected.sum()} in coverage.py's worked polygon, "
          f"{differ.sum()} differ, all within half a cell's diagonal of its edge: {near.all()}")
    assert live.sum() > 0.9 * plan.target.area / res ** 2
    assert near.all()
    skipped = values == SKIPPED  # at the end: the target's cells not worked
    assert shapely.contains_xy(plan.target, cx[skipped], cy[skipped]).all()
    off = skipped != shapely.contains_xy(cov.skipped, cx, cy)
    edges = shapely.union_all([cov.skipped.boundary, polygon.boundary])
    assert (shapely.distance(edges, shapely.points(cx[off], cy[off])) <= res * math.sqrt(0.5)).all()
    print(f"skipped cells {skipped.sum()}, {off.sum()} differ from coverage.py's skipped, all at its edges")


def test_a_train_not_at_the_routes_start_is_refused(tmp_path):
    scene_file = small_field(tmp_path)
    scene = load_field_scene(scene_file)
    plan = plan_field(scene.field, TRAIN, scene.options(TRAIN))
    follow = Follow(plan, TRAIN)
    points = [(20.0 - 5.0 * k, 3.0) for k in range(TRAIN.n)]
    steering, speed, lowered = follow.answer(points, [0.0] * TRAIN.n, 0.0, 3.0)
    assert follow.status == REFUSED and speed == 0.0 and not lowered
    assert "not at the route's start" in follow.reason and "\n" not in follow.reason


@pytest.mark.slow
def test_hostile_inputs_are_refused_in_one_line(tmp_path):
    scene_file = small_field(tmp_path / "field")
    other = tmp_path / "field" / "other.yaml"
    other.write_text("name: other\nboundary: [[0, 0], [170, 0], [170, 100], [0, 100]]\nheadlands: 2\n")
    assert mta("field", "plan", scene_file, "--out", tmp_path / "plan").returncode == 0
    assert_refused(mta("follow", "--plan", tmp_path / "plan", "--field", other), "--plan", "a plan of field 'other'")
    narrow = tmp_path / "narrow.yaml"
    narrow.write_text(TRAIN_FILE.read_text().replace("width: 12              # m: the working width",
                                                     "width: 6              # m: the working width"))
    assert_refused(mta("follow", "--plan", tmp_path / "plan", "--train", narrow), "--plan", "6 m implement")
    broken = tmp_path / "broken.yaml"
    broken.write_text("name: broken\nfield: nowhere.yaml\n")
    assert_refused(mta("follow", "--field", broken), "field", "not found")
