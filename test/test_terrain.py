"""The ground (physics/terrain.py) against what cannot drift: the geometry of a rigid body resting
on a surface, the statics of a box on a side slope, polynomials a bicubic spline reproduces, and
hostile grids refused in one line."""
from __future__ import annotations

import math
import pickle

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mta_sim_ros.physics.terrain import (
    MAX_SLOPE_DEG,
    OffTerrain,
    Plane,
    Surface,
    grid_from,
    orientation,
    plane_from,
    read_heights,
    rollover_margin,
    tipping_side_slope,
)
from mta_sim_ros.validate import InputError


def rotation(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """REP-103's fixed-axis roll, pitch, yaw (R = Rz(yaw) Ry(pitch) Rx(roll)), written out."""
    cr, sr, cp, sp, cy, sy = (math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch), math.cos(yaw),
                              math.sin(yaw))
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    return rz @ ry @ rx


slopes = st.floats(-1.5, 1.5)


@settings(max_examples=300, deadline=None)
@given(gx=slopes, gy=slopes, heading=st.floats(-math.pi, math.pi))
def test_a_cart_rests_on_the_surface_heading_where_it_heads(gx, gy, heading):
    """With yaw = heading and orientation()'s roll and pitch, the body's z axis is the surface's
    normal and its x axis lies in the surface, its horizontal part along the heading."""
    roll, pitch = orientation(heading, Surface(0.0, gx, gy))
    R = rotation(roll, pitch, heading)
    normal = np.array([-gx, -gy, 1.0]) / math.sqrt(1 + gx * gx + gy * gy)
    np.testing.assert_allclose(R[:, 2], normal, atol=1e-12)
    x_axis = R[:, 0]
    assert abs(x_axis @ normal) < 1e-12  # in the tangent plane
    assert abs(math.atan2(x_axis[1], x_axis[0]) - heading) < 1e-9 or abs(abs(heading) - math.pi) < 1e-9


def test_signs_follow_rep_103():
    """Uphill ahead: nose up, so pitch < 0 (about y, positive nose down); ground rising on the
    left: left side up, roll > 0."""
    assert orientation(0.0, Surface(0.0, 0.1, 0.0)) == (0.0, -math.atan(0.1))
    roll, pitch = orientation(0.0, Surface(0.0, 0.0, 0.1))
    assert roll == pytest.approx(math.atan(0.1), rel=1e-15) and pitch == 0.0
    roll, _ = orientation(math.pi / 2, Surface(0.0, 0.1, 0.0))  # heading +y, ground rising to its right
    assert roll == pytest.approx(-math.atan(0.1), rel=1e-12)


@pytest.mark.parametrize("track, height", [(1.8, 1.1), (2.4, 0.9), (1.5, 1.6)])
def test_the_rollover_margin_is_the_uphill_wheels_share_of_a_box_on_a_side_slope(track, height):
    """A box (mass m, track t, centre of mass h over the ground) on a side slope b: its two wheel
    loads from the balance of forces normal to the slope and of moments about the centre of mass,
    solved as a linear system; the margin is the uphill load over half the total."""
    m, g = 1000.0, 9.80665
    for b in np.linspace(0.0, 0.6, 13):
        # N_up + N_down = m g cos b;  moments about C: (N_down - N_up) t/2 = m g sin b h (friction at the wheels)
        A = np.array([[1.0, 1.0], [-track / 2, track / 2]])
        n_up, n_down = np.linalg.solve(A, [m * g * math.cos(b), m * g * math.sin(b) * height])
        assert rollover_margin(track, height, b) == pytest.approx(n_up / (m * g * math.cos(b) / 2), abs=1e-12)
    b0 = tipping_side_slope(track, height)
    assert math.tan(b0) == pytest.approx(track / (2 * height), rel=1e-15)
    assert rollover_margin(track, height, b0) == pytest.approx(0.0, abs=1e-14)
    assert rollover_margin(track, height, -b0 * 1.1) < 0 and rollover_margin(track, height, 0.0) == 1.0


def test_a_plane_is_its_equation():
    plane = plane_from(5.0, -2.0)
    assert plane == Plane(0.05, -0.02)
    assert plane.at(100.0, 50.0) == Surface(0.05 * 100.0 - 0.02 * 50.0, 0.05, -0.02)


def cubic(x, y):
    """A polynomial of degree 3 in each of x and y: in the space of a bicubic spline."""
    return 0.05 * x + 0.02 * y + 1e-3 * x * x - 5e-4 * x * y + 2e-6 * x ** 3 - 1e-6 * x * y * y + 1.0


def cubic_gradient(x, y):
    return (0.05 + 2e-3 * x - 5e-4 * y + 6e-6 * x * x - 1e-6 * y * y, 0.02 - 5e-4 * x - 2e-6 * x * y)


def test_a_grid_reproduces_a_cubic_surface_between_its_nodes():
    xs, ys = 10.0 + 5.0 * np.arange(12), -20.0 + 5.0 * np.arange(9)
    grid = grid_from(cubic(xs[None, :], ys[:, None]), (10.0, -20.0), 5.0)
    rng = np.random.default_rng(7)
    for x, y in zip(rng.uniform(xs[0], xs[-1], 200), rng.uniform(ys[0], ys[-1], 200)):
        s = grid.at(x, y)
        assert s.z == pytest.approx(cubic(x, y), abs=1e-9)
        assert (s.dzdx, s.dzdy) == pytest.approx(cubic_gradient(x, y), abs=1e-9)


def test_a_grids_slope_is_continuous_across_its_nodes():
    rng = np.random.default_rng(3)
    grid = grid_from(rng.uniform(0.0, 2.0, (8, 10)), (0.0, 0.0), 10.0)
    for x in (20.0, 30.0, 40.0):  # nodes
        left, right = grid.at(x - 1e-7, 35.0), grid.at(x + 1e-7, 35.0)
        assert abs(left.dzdx - right.dzdx) < 1e-6 and abs(left.z - right.z) < 1e-6


def test_a_point_off_the_grid_is_said_not_extrapolated():
    grid = grid_from(np.zeros((4, 4)), (0.0, 0.0), 1.0)
    assert grid.at(3.0, 3.0).z == 0.0
    with pytest.raises(OffTerrain, match=r"\(3.001, 0.000\) m is off the terrain grid x in \[0, 3\]"):
        grid.at(3.001, 0.0)


def refused(call, *expected):
    with pytest.raises(InputError) as err:
        call()
    message = str(err.value)
    assert "\n" not in message, message
    for text in expected:
        assert text in message, (text, message)
    return message


def flat(rows, cols):
    return np.zeros((rows, cols))


@pytest.mark.parametrize("heights, origin, spacing, expected", [
    (np.full((5, 5), np.nan), (0, 0), 1.0, ("heights: nan at row 0, column 0", "finite")),
    (np.where(np.eye(5) > 0, np.inf, 0.0), (0, 0), 1.0, ("heights: inf at row 0, column 0",)),
    (flat(1, 1), (0, 0), 1.0, ("1 x 1 nodes", "at least 4 x 4")),
    (flat(3, 50), (0, 0), 1.0, ("3 x 50 nodes",)),
    (np.zeros(16), (0, 0), 1.0, ("shape (16,)", "2-D array")),
    (np.zeros((4, 4, 4)), (0, 0), 1.0, ("shape (4, 4, 4)",)),
    (np.array([["a"] * 4] * 4), (0, 0), 1.0, ("2-D array of numbers",)),
    (np.diag([0.0, 10.0, 0.0, 0.0, 0.0]), (0, 0), 5.0, ("a rise of 10 m over 5 m", f"at most {MAX_SLOPE_DEG:g} deg")),
    (flat(4, 4), (0, 0), 0.0, ("spacing: 0", "in [0.01, 100000] m")),
    (flat(4, 4), (0, 0), -1.0, ("spacing: -1",)),
    (flat(4, 4), (0, 0), float("nan"), ("spacing: nan",)),
    (flat(4, 4), (0, 0), True, ("spacing: True",)),
    (flat(4, 4), (0,), 1.0, ("origin: (0,)", "two numbers within +-1e+07 m")),
    (flat(4, 4), (0, float("inf")), 1.0, ("origin:",)),
    (flat(4, 4), "00", 1.0, ("origin: '00'",)),
    (np.full((4, 4), 1e308), (0, 0), 1.0, ("heights: 1e+308 at row 0, column 0", "within +-100000 m")),  # overflowed
    (flat(4, 4), (1e300, 0), 1.0, ("origin:", "within +-1e+07 m")),
    (flat(4, 4), (0, 0), 1e300, ("spacing: 1e+300", "in [0.01, 100000] m")),
    (flat(4, 4), (0, 0), 0.005, ("spacing: 0.005", "in [0.01, 100000] m")),  # as the scene's rule (schema.py)
])
def test_hostile_grids_are_refused_in_one_line(heights, origin, spacing, expected):
    refused(lambda: grid_from(heights, origin, spacing, "terrain", "field.yaml"), *expected, "of field.yaml")


def test_too_many_nodes_are_refused_before_any_work():
    big = np.broadcast_to(np.float64(0.0), (5000, 5000))  # no memory: a view of one number
    refused(lambda: grid_from(big, (0, 0), 1.0), "5000 x 5000 nodes", "at most")


@pytest.mark.parametrize("grade, cross, expected", [
    (200.0, 0.0, "63.4 deg"),
    (120.0, 120.0, "59.5"),  # atan(1.697) = 59.5 deg: taken
    (float("nan"), 0.0, "grade_percent: nan"),
    (0.0, float("inf"), "cross_slope_percent: inf"),
    (0.0, "5", "cross_slope_percent: '5'"),
])
def test_planes_past_sixty_degrees_or_not_numbers_are_refused(grade, cross, expected):
    if expected == "59.5":
        assert plane_from(grade, cross).grade == 1.2
        return
    refused(lambda: plane_from(grade, cross), expected)


def test_grid_files_npy_and_csv(tmp_path):
    heights = np.arange(20.0).reshape(4, 5) * 0.1
    np.save(tmp_path / "h.npy", heights)
    np.savetxt(tmp_path / "h.csv", heights, delimiter=",")
    np.testing.assert_array_equal(read_heights(tmp_path / "h.npy"), heights)
    np.testing.assert_array_equal(read_heights(tmp_path / "h.csv"), heights)
    (tmp_path / "bom.csv").write_bytes(b"\xef\xbb\xbf" + (tmp_path / "h.csv").read_bytes())  # a spreadsheet's export
    np.testing.assert_array_equal(read_heights(tmp_path / "bom.csv"), heights)
    (tmp_path / "ragged.csv").write_text("1,2,3,4\n1,2,3\n1,2,3,4\n1,2,3,4\n")
    refused(lambda: read_heights(tmp_path / "ragged.csv"), "file:", "a grid of numbers")
    (tmp_path / "words.csv").write_text("a,b\n")
    refused(lambda: read_heights(tmp_path / "words.csv"), "a grid of numbers")
    (tmp_path / "empty.npy").write_bytes(b"")
    refused(lambda: read_heights(tmp_path / "empty.npy"), "a grid of numbers")
    with open(tmp_path / "pickled.npy", "wb") as f:  # an object array needs pickle: never loaded
        np.save(f, np.array([{"a": 1}], dtype=object), allow_pickle=True)
    refused(lambda: read_heights(tmp_path / "pickled.npy"), "a grid of numbers")
    (tmp_path / "evil.npy").write_bytes(pickle.dumps([1, 2]))
    refused(lambda: read_heights(tmp_path / "evil.npy"), "a grid of numbers")
    refused(lambda: read_heights(tmp_path / "nowhere.csv"), "nowhere.csv", "No such file")
    refused(lambda: read_heights(tmp_path), "a file (.npy, .csv")
    (tmp_path / "h.tif").write_bytes(b"II*\0")
    refused(lambda: read_heights(tmp_path / "h.tif"), "a .npy or .csv grid")
