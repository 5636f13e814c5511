"""`mta analyze`: the report of a recorded run holds the physics the model promises.

Bags are made as a user makes them (`mta run` in a separate process) from the shipped scenes, and
analysed with `mta analyze` as a user runs it; the numbers are then checked against closed forms
(steady circles, off-tracking), against conservation of energy (with the bound the check's own
discretisation allows), and against the bag itself (CSV round trip, comparisons).
"""
from __future__ import annotations

import json
import math
import subprocess
import sys
from decimal import Decimal
from pathlib import Path

import numpy as np
import pytest

from mta_sim_ros.bag import BagWriter, read_messages
from mta_sim_ros.messages.topics import TOPICS, command_messages, output_messages, qualified
from mta_sim_ros.physics.loader import load_scene
from mta_sim_ros.physics.steady import steady_circle
from mta_sim_ros.run.simulation import run_scene
from mta_sim_ros import analysis
from mta_sim_ros.tools.run import run_metadata

pytestmark = pytest.mark.slow  # its bags are three shipped scenes run in full

REPO = Path(__file__).resolve().parents[1]
SCENES = REPO / "config" / "scenes"


def mta(*args, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mta_sim_ros.cli", *map(str, args)], capture_output=True,
                          text=True, cwd=cwd or REPO, timeout=600)


@pytest.fixture(scope="module")
def bags(tmp_path_factory) -> dict[str, Path]:
    """The shipped scenes, each run by `mta run` into its own bag."""
    tmp = tmp_path_factory.mktemp("bags")
    out = {}
    for name in ("steady_turn", "headland_turn", "slalom"):
        bag = tmp / f"{name}.mcap"
        done = mta("run", "--scene", SCENES / f"{name}.yaml", "--bag", bag, "--quiet")
        assert done.returncode == 0, done.stderr
        out[name] = bag
    return out


@pytest.fixture(scope="module")
def reports(bags, tmp_path_factory) -> dict[str, Path]:
    """`mta analyze` of each bag, into its own folder."""
    tmp = tmp_path_factory.mktemp("reports")
    out = {}
    for name, bag in bags.items():
        folder = tmp / name
        done = mta("analyze", bag, "-o", folder)
        assert done.returncode == 0, done.stderr
        assert f"report: {folder}" in done.stdout
        out[name] = folder
    return out


def summary(folder: Path) -> dict:
    return json.loads((folder / "summary.json").read_text())["summaries"]


# -------------------------------------------------------------------------------- steady turn

# Relative tolerance of the fitted steady radii. The steering of steady_turn is constant from
# t = 4 s; by the last third (t >= 80 s) the train has run 228 m, about 38 lengths of its longest
# cart, and a forward hitch transient decays like exp(-s / l): it is gone to round-off. The bag's
# positions are float64, and the geometric circle fit of exact circle data is exact to ~1e-13
# (seen: 4e-13). 1e-9 leaves four orders for platform round-off while any error of the model's
# kinematics (a wrong l, a, or sign in the chain) moves the radii by 1e-3 or more.
RADIUS_RTOL = 1e-9


def test_steady_turn_radii_are_the_closed_form_circles(reports):
    """Constant steering psi_1: every B_k settles on R_B1 = l_1 / tan psi_1,
    R_B{k+1}^2 = R_Bk^2 + a_k^2 - l_{k+1}^2 (MODEL.md); the circle fit of each B_k over the last
    third of the run gives these radii."""
    s = summary(reports["steady_turn"])
    steady = s["steady"]
    assert steady["constant"], steady
    assert steady["steering_rad"] == pytest.approx(0.15, abs=1e-12)
    scene = load_scene(SCENES / "steady_turn.yaml")
    closed = steady_circle(scene.train, 0.15)
    assert [c["cart"] for c in steady["carts"]] == [c.name for c in scene.train.carts]
    for entry, R in zip(steady["carts"], closed.R_B):
        assert entry["closed_R_B_m"] == pytest.approx(R, rel=1e-15)
        assert abs(entry["fit_R_B_m"] - R) / R < RADIUS_RTOL, entry
        assert entry["fit_rms_m"] < RADIUS_RTOL * R  # the points lie on one circle: the turn is steady
    # the report says it in words too
    md = (reports["steady_turn"] / "summary.md").read_text()
    assert "Steady turn (steering 0.150000 rad" in md


def test_steady_turn_off_tracking_is_the_difference_of_radii(reports, bags):
    """On concentric circles the last axle runs R_B1 - R_Bn inside the tractor's axle path.
    The path is the polyline through B_1's samples, whose chords cut inside the circle, towards
    the trailers' axles, by at most the sagitta L^2 / (8 R_B1) (L = the longest chord): the
    measured off-tracking may fall short of R_B1 - R_Bn by that much and must not exceed it (the
    train spirals in from the straight start without overshooting its steady off-tracking)."""
    s = summary(reports["steady_turn"])
    closed = steady_circle(load_scene(SCENES / "steady_turn.yaml").train, 0.15)
    data = analysis.load_bag(bags["steady_turn"])
    B1 = data.axles()[:, 0]
    chord = np.hypot(*np.diff(B1, axis=0).T).max()
    sagitta = chord**2 / (8 * closed.R_B[0])
    for entry, R in zip(s["off_tracking"], closed.R_B[1:]):
        expected = closed.R_B[0] - R
        assert entry["signed_m"] > 0  # inside the left turn
        assert -sagitta - 1e-9 <= entry["max_abs_m"] - expected <= 1e-9, (entry, expected, sagitta)
        assert entry["time_s"] > 10.0  # reached on the circle, not in the spiral-in


def test_off_tracking_distance_is_the_exact_nearest_point(bags):
    """The k-d tree search of the nearest point on B_1's path up to t gives the brute-force answer."""
    data = analysis.load_bag(bags["headland_turn"])
    B = data.axles()
    upto = np.arange(len(B))
    d, at_end = analysis.distance_to_path(B[:, 2], B[:, 0], upto)
    for j in range(1, len(B), 13):
        a, seg = B[:j, 0], B[1:j + 1, 0] - B[:j, 0]
        len2 = (seg * seg).sum(axis=1)
        ok = len2 > 0
        a, seg, len2 = a[ok], seg[ok], len2[ok]
        u = np.clip(((B[j, 2] - a) * seg).sum(axis=1) / len2, 0, 1)
        brute = np.hypot(*(B[j, 2] - a - u[:, None] * seg).T).min()
        assert abs(abs(d[j]) - brute) <= 1e-12, j


# -------------------------------------------------------------------------------- energy balance


def ramp_bound(scene) -> float:
    """Largest error, J, that the held speed set-point puts into the check's traction work.

    The governor's force F = kp (v_set - V) + I jumps by kp dv at each tick where the set-point
    steps by dv; the bag logs the power at the end of each tick, under that tick's set-point, so
    the trapezoid sees each jump one sample (h) late: an error of at most h/2 V kp |dv| per tick,
    summed over a ramp h/2 V_max kp |Delta v_ramp|. No cancellation between ramps is assumed.
    """
    h = 1.0 / scene.publish_rate
    kp = scene.train.traction.kp
    speeds = scene.speed.value
    v_max = max(speeds)
    return sum(0.5 * h * v_max * kp * abs(b - a) for a, b in zip(speeds, speeds[1:]))


def test_headland_turn_energy_balance(reports):
    """Power balance F_A1 V - sum F_Bk s'_Bk = dT/dt (MODEL.md), integrated over the headland
    turn from the bag alone: traction work = change of kinetic energy + work of the resistances.

    The model holds this to round-off (test_physics), so the residual is the check's own error at
    the bag's 50 Hz: O(h^2) from the central differences and the trapezoid (on the turn the
    central difference shortens s'_Bk by (w h)^2 / 6 ~ 2e-6 relative, a few J), and O(h) from the
    two speed ramps (3 -> 2 -> 3 m/s), bounded by ramp_bound: 2 x 1020 J at h = 0.02 s, kp = 34 kN s/m.
    Bound: ramp_bound + 50 J, about 2e-4 of the 10.3 MJ of traction work (seen: 144 J, 1.4e-5:
    the two ramps' errors have opposite signs). The residual over every [0, t] is held to the same
    bound; at t = 12 s the kinetic energy has fallen by 85 kJ, 40 times the bound: leaving out the
    yaw inertias (running residual 4.1 kJ) or taking the seeder's mass 5 % too large (2.2 kJ) fails
    this test (both tried), and so does 1 % of one cart's resistance (tens of kJ).
    """
    scene = load_scene(SCENES / "headland_turn.yaml")
    bound = ramp_bound(scene) + 50.0
    assert bound == pytest.approx(2 * 1020 + 50)
    e = summary(reports["headland_turn"])["energy_balance"]
    assert e["samples"] == 3501
    assert e["traction_work_J"] > 1e7
    assert abs(e["residual_J"]) < bound, e
    assert abs(e["relative_residual"]) < 2.1e-4
    assert e["max_abs_running_residual_J"] < bound, e
    assert e["kinetic_energy_start_J"] == pytest.approx(0.5 * 34000 * 3.0**2)  # straight at 3 m/s: sum m V^2 / 2


def test_steady_turn_energy_balance_is_second_order(reports):
    """With a constant set-point only the O(h^2) part remains: on the circle the central
    difference of B_k gives its speed times sin(w h) / (w h) ~ 1 - (w h)^2 / 6 (w = V / R_B1, the
    yaw rate), so the resistance work is under-counted by (w h)^2 / 6 of itself. The residual must
    be of that size: below 1.5 (w h)^2 / 6 of the traction work (seen: 1.40e-6 against 1.53e-6)."""
    scene = load_scene(SCENES / "steady_turn.yaml")
    closed = steady_circle(scene.train, 0.15)
    w_h = 3.0 / closed.R_B[0] / scene.publish_rate
    e = summary(reports["steady_turn"])["energy_balance"]
    assert abs(e["relative_residual"]) < 1.5 * w_h**2 / 6, e


# -------------------------------------------------------------------------------- summary figures


def test_summary_figures_of_the_headland_turn(reports, bags):
    """The summary repeats what `mta run` reports (distance, power, hitch angles) from the bag."""
    s = summary(reports["headland_turn"])
    assert s["duration_s"] == pytest.approx(70.0)
    assert s["distance_A1_m"] == pytest.approx(180.0, rel=1e-3)
    p = s["power_kW"]
    assert p["min"] < p["mean"] < p["max"]
    assert s["traction_energy_kWh"] == pytest.approx(p["mean"] * 70.0 / 3600.0)
    assert set(s["max_abs_hitch_angle_deg"]) == {"tractor-air_cart", "air_cart-seeder"}
    report_md = bags["headland_turn"].with_suffix(".md").read_text()  # `mta run`'s own report
    for joint, deg in s["max_abs_hitch_angle_deg"].items():
        assert f"largest hitch angle {joint} | {deg:.2f} deg" in report_md
    assert f"{p['min']:.1f} / {p['mean']:.1f} / {p['max']:.1f} kW" in report_md
    assert not s["steady"]["constant"] or s["steady"].get("reason") == "straight (steering 0): no circle"
    md = (reports["headland_turn"] / "summary.md").read_text()
    for text in ("distance travelled by A_1", "traction energy", "off-tracking of B (seeder)",
                 "energy balance residual", "## Definitions"):
        assert text in md


# -------------------------------------------------------------------------------- CSV


def test_csv_round_trips_the_bag_exactly(reports, bags):
    """Every value of every topic read back from the CSV equals the bag's value (floats written
    with repr), the time column is the exact log time, and the headers name the carts."""
    folder = reports["headland_turn"] / "csv"
    by_topic: dict[str, list] = {}
    for topic, t_ns, msg in read_messages(bags["headland_turn"]):
        by_topic.setdefault(topic, []).append((t_ns, msg))
    assert sorted(p.name for p in folder.glob("*.csv")) == sorted(t.strip("/") + ".csv" for t in by_topic)
    for topic, msgs in by_topic.items():
        header, rows = analysis.read_csv(folder / (topic.strip("/") + ".csv"))
        assert header[0] == "time_s" and len(rows) == len(msgs), topic
        for row, (t_ns, msg) in zip(rows, msgs):
            assert int(Decimal(row[0]) * 10**9) == t_ns
            values = dict(zip(header[1:], row[1:]))
            if topic == "/hitch_poses":
                for k, (name, pose) in enumerate(zip(["tractor", "air_cart", "seeder"], msg.poses)):
                    assert float(values[f"A{k + 1}_{name}_x_m"]) == pose.position.x
                    assert float(values[f"A{k + 1}_{name}_y_m"]) == pose.position.y
                    heading = float(values[f"A{k + 1}_{name}_heading_rad"])
                    assert heading == analysis.quaternion_yaw(pose.orientation)
                    assert -math.pi < heading <= math.pi
                    z, w = pose.orientation.z, pose.orientation.w  # the same rotation about z:
                    assert (math.cos(heading), math.sin(heading)) == pytest.approx((w * w - z * z, 2 * w * z),
                                                                                    abs=1e-15)
            elif topic == "/cart_velocities":
                for name, v, th, f in zip(msg.name, msg.velocity, msg.position, msg.effort):
                    assert float(values[f"{name}_com_speed_mps"]) == v
                    assert float(values[f"{name}_heading_rad"]) == th
                    assert float(values[f"{name}_resistance_N"]) == f
            elif topic == "/clock":
                assert (int(values["clock_sec"]), int(values["clock_nanosec"])) == (msg.clock.sec, msg.clock.nanosec)
            elif topic in ("/tf", "/tf_static"):  # the train's frames (test_frames.py): fields flattened
                for i, tf in enumerate(msg.transforms):
                    assert values[f"transforms.{i}.child_frame_id"] == tf.child_frame_id
                    assert float(values[f"transforms.{i}.transform.translation.x"]) == tf.transform.translation.x
                    assert float(values[f"transforms.{i}.transform.rotation.w"]) == tf.transform.rotation.w
            elif topic == "/joint_states":
                assert [float(values[f"position.{i}"]) for i in range(len(msg.position))] == list(msg.position)
            elif topic == "/odom":
                assert float(values["twist.twist.angular.z"]) == msg.twist.twist.angular.z
            elif topic == "/robot_description":
                assert values["data"] == msg.data  # the URDF, its line breaks kept
            else:
                (value,) = values.values()
                assert float(value) == msg.data


def test_namespaced_node_style_bag(tmp_path):
    """A bag as the node writes it under a namespace (/unit1/hitch_poses, ...), starting at a
    clock offset (after a reset), with a topic the analysis does not know (/diagnostics): topics
    are matched by their last name component, times start from the first pose, and the unknown
    topic is exported with its fields flattened (union of the columns of its messages)."""
    scene_path = tmp_path / "scene.yaml"
    scene_path.write_text(f"name: short_turn\ntrain: {REPO / 'config/trains/default.yaml'}\nduration: 3\n"
                          "initial: {speed: 3.0}\nsteering: {table: {time: [0, 1], angle: [0, 0.1]}}\n"
                          "publish_rate: 20\n")
    scene = load_scene(scene_path)
    names = [c.name for c in scene.train.carts]
    bag = tmp_path / "node_run.mcap"
    offset_ns = 100 * 10**9
    with BagWriter(str(bag), metadata={"mta_sim_ros": run_metadata(scene, {"method": "rk4"})}) as w:
        for topic, type_name in TOPICS.items():
            w.add_topic(qualified(topic, "/unit1"), type_name)
        w.add_topic("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray")

        diagnostics = {0.0: [{"key": "lag_s", "value": "0"}],  # at 0 s and 1 s, in log-time order
                       1.0: [{"key": "lag_s", "value": "0"}, {"key": "rtf", "value": "1.0"}]}

        def record(out):
            stamp = offset_ns + round(out.t * 1e9)
            for topic, msg in {**output_messages(out, names), **command_messages(out)}.items():
                w.write(qualified(topic, "/unit1"), msg, stamp)
            if round(out.t, 9) in diagnostics:
                w.write("/diagnostics", {"status": [{"name": "sim", "message": "ok",
                                                     "values": diagnostics[round(out.t, 9)]}]}, stamp)

        run_scene(scene, on_output=record)
    done = mta("analyze", bag, cwd=tmp_path)  # default folder: reports/<bag stem>/
    assert done.returncode == 0, done.stderr
    folder = tmp_path / "reports" / "node_run"
    assert f"report: {Path('reports') / 'node_run'}" in done.stdout
    s = summary(folder)
    assert s["topics"]["hitch_poses"] == "/unit1/hitch_poses"
    assert s["scene"] == "short_turn"
    assert s["duration_s"] == pytest.approx(3.0)
    assert s["energy_balance"]["samples"] == 61
    header, rows = analysis.read_csv(folder / "csv" / "unit1__hitch_poses.csv")
    assert header[1:4] == ["A1_tractor_x_m", "A1_tractor_y_m", "A1_tractor_heading_rad"]
    assert rows[0][0] == "100.000000000"
    header, rows = analysis.read_csv(folder / "csv" / "diagnostics.csv")
    assert "status.0.values.1.key" in header and "status.0.message" in header
    column = header.index("status.0.values.1.key")
    assert rows[0][column] == "" and rows[1][column] == "rtf"


# -------------------------------------------------------------------------------- plots


def test_plots_exist_and_are_nontrivial(reports):
    """Each figure is a PNG about 800 px wide, under 200 KB, and has drawing on it (many colours,
    a few percent of the pixels not white)."""
    from matplotlib.image import imread

    for name in ("steady_turn", "headland_turn"):
        for fig in analysis.FIGURES:
            path = reports[name] / fig
            raw = path.read_bytes()
            assert raw[:8] == b"\x89PNG\r\n\x1a\n", path
            assert 10_000 < len(raw) < 200_000, (path, len(raw))
            img = imread(path)[..., :3]
            assert 780 <= img.shape[1] <= 820 and 300 <= img.shape[0] <= 900, (path, img.shape)
            drawn = np.any(img < 0.95, axis=-1).mean()
            colours = len(np.unique((img * 255).astype(np.uint8).reshape(-1, 3), axis=0))
            assert drawn > 0.02 and colours > 50, (path, drawn, colours)
        assert "![trajectory](trajectory.png)" in (reports[name] / "summary.md").read_text()


# -------------------------------------------------------------------------------- comparisons


def test_comparison_of_a_bag_with_itself_is_zero(bags, tmp_path):
    """The same run twice: every output differs by exactly 0 after interpolation onto common times."""
    folder = tmp_path / "self"
    done = mta("analyze", bags["headland_turn"], bags["headland_turn"], "-o", folder)
    assert done.returncode == 0, done.stderr
    report = json.loads((folder / "summary.json").read_text())
    (rows,) = report["differences"].values()
    assert len(rows) >= 3 * 5 + 2 + 4  # per cart A, B, heading, speed, resistance; 2 joints; 4 signals
    assert all(r["max_abs_diff"] == 0.0 for r in rows), [r for r in rows if r["max_abs_diff"]]
    assert report["labels"] == ["headland_turn", "headland_turn_2"]
    assert (folder / "csv" / "headland_turn_2" / "hitch_poses.csv").is_file()
    for fig in analysis.FIGURES:
        assert (folder / fig).is_file()


def test_comparison_of_two_scenes_reports_differences(bags, tmp_path):
    """Headland turn against slalom (same train, other steering and speed): positions, headings,
    hitch angles, power and both steering signals differ; the default folder is
    reports/compare_<a>_<b>/."""
    done = mta("analyze", bags["headland_turn"], bags["slalom"], cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    folder = tmp_path / "reports" / "compare_headland_turn_slalom"
    report = json.loads((folder / "summary.json").read_text())
    rows = {r["output"]: r for r in report["differences"]["slalom - headland_turn"]}
    for output in ("A_1 position (tractor)", "B_3 position (seeder)", "heading (seeder)",
                   "hitch angle air_cart-seeder", "traction power", "steering command", "applied steering",
                   "speed set-point", "centre-of-mass speed (tractor)"):
        assert rows[output]["max_abs_diff"] > 0, output
    assert rows["speed set-point"]["max_abs_diff"] == pytest.approx(1.0)  # 3 m/s against 2 m/s in the turn
    assert rows["steering command"]["max_abs_diff"] > 10  # deg
    md = (folder / "summary.md").read_text()
    assert "## Differences: slalom - headland_turn" in md
    assert set(report["summaries"]) == {"headland_turn", "slalom"}
