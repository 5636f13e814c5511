"""The train on a height grid (a scene's ``terrain.heights``) against what cannot drift: scipy's
own spline through the same nodes, a grid sampled from a plane against the tilted plane's closed
forms, the energy balance with the potential energy m g z(C_k) read by scipy, the readable
reference against the compiled kernel, and the borders: hostile grid files in scenes, a train
leaving the grid, levels that cannot take one, a bag that replays without the grid's file."""
from __future__ import annotations

import dataclasses
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trains
from scipy.interpolate import RectBivariateSpline

from mta_sim_ros.physics import kernel, loader
from mta_sim_ros.physics.dynamics import Model
from mta_sim_ros.physics.geometry import cart_points
from mta_sim_ros.physics.guards import ModelValidityError
from mta_sim_ros.physics.levels import make_level
from mta_sim_ros.physics.terrain import Plane, Stance, grid_from, orientation
from mta_sim_ros.run.simulation import Simulation, run_scene
from mta_sim_ros.validate import InputError

G = 9.80665
CONFIG = Path("config")  # the shipped files (the tests run from the repository)


def hills(nx: int = 30, ny: int = 26, spacing: float = 8.0, origin=(-60.0, -100.0)):
    """Smooth hills up to ~20 % (a sum of sines), and the grid through them."""
    xs = origin[0] + spacing * np.arange(nx)
    ys = origin[1] + spacing * np.arange(ny)
    X, Y = np.meshgrid(xs, ys)
    z = 3.0 * np.sin(X / 25.0) * np.cos(Y / 40.0) + 1.5 * np.sin((X + Y) / 17.0) + 0.03 * X
    return grid_from(z, origin, spacing)


def plane_grid(gx: float, gy: float):
    xs = -100.0 + 10.0 * np.arange(41)
    ys = -100.0 + 10.0 * np.arange(21)
    return grid_from(gx * xs[None, :] + gy * ys[:, None] + 5.0, (-100.0, -100.0), 10.0)


def on_grid(tr, grid):
    return dataclasses.replace(tr, relief=grid)


# -- the surface: the kernel's spline is scipy's ----------------------------------------------------
def test_the_kernels_surface_is_scipys_spline_through_the_nodes():
    grid = hills()
    ref = RectBivariateSpline(grid.ys, grid.xs, grid.heights, kx=3, ky=3, s=0)
    rng = np.random.default_rng(3)
    xs = rng.uniform(grid.xs[0], grid.xs[-1], 500)
    ys = rng.uniform(grid.ys[0], grid.ys[-1], 500)
    z, zx, zy = kernel.surfaces_of(grid.block, xs, ys)
    np.testing.assert_allclose(z, ref(ys, xs, grid=False), rtol=0, atol=1e-11)
    np.testing.assert_allclose(zx, ref(ys, xs, dy=1, grid=False), rtol=0, atol=1e-12)
    np.testing.assert_allclose(zy, ref(ys, xs, dx=1, grid=False), rtol=0, atol=1e-12)
    X, Y = np.meshgrid(grid.xs, grid.ys)
    at_nodes = kernel.surfaces_of(grid.block, X.ravel(), Y.ravel())[0].reshape(X.shape)
    np.testing.assert_allclose(at_nodes, grid.heights, rtol=0, atol=1e-11)  # through every node
    assert grid.at(xs[0], ys[0]).z == pytest.approx(float(ref(ys[0], xs[0])[0, 0]), abs=1e-11)


# -- a grid sampled from a plane is the tilted plane ------------------------------------------------
@pytest.mark.parametrize("grade", [0.05, -0.12, 0.3])
def test_a_grid_of_a_grade_climbs_as_the_tilted_plane(grade):
    """Straight up a grade a at horizontal speed V_h: each cart's grade resistance is m g tan(a) per
    horizontal metre, its power m g tan(a) V_h = m g sin(a) V (V = V_h / cos a along the ground):
    the tilted plane's; the rolling resistance takes the same normal load f m g cos(a)."""
    tr = trains.train(3, draft=False)
    grid_model, plane_model = Model(on_grid(tr, plane_grid(grade, 0.0))), Model(dataclasses.replace(
        tr, terrain=Plane(grade, 0.0)))
    cos_a = 1.0 / math.sqrt(1.0 + grade * grade)
    y = np.zeros(grid_model.layout.size)
    y[grid_model.layout.speed] = 3.0 * cos_a
    on_grid_terms = grid_model.terms(y, 0.0, 3.0)
    y_plane = y.copy()
    y_plane[plane_model.layout.speed] = 3.0
    on_plane_terms = plane_model.terms(y_plane, 0.0, 3.0)
    for cart, f in zip(tr.carts, on_grid_terms.grade):
        assert f == pytest.approx(cart.mass * G * grade, rel=1e-12)
    grid_power = grid_model.outputs(0.0, y, 0.0, 3.0).grade_power
    plane_power = plane_model.outputs(0.0, y_plane, 0.0, 3.0).grade_power
    assert grid_power == pytest.approx(plane_power, rel=1e-12)
    assert on_grid_terms.resistance == pytest.approx(on_plane_terms.resistance, rel=1e-12)


def test_a_grid_of_a_side_slope_holds_the_axles_as_the_tilted_plane():
    """Straight along the contour of a side slope (rise b per horizontal metre across the path) at
    steady speed: the axles' lateral forces sum to the horizontal force of gravity's potential,
    m g b per cart, which they hold (the no-slip constraint's reaction)."""
    b = 0.2
    tr = trains.train(3, draft=False)
    grid_model = Model(on_grid(tr, plane_grid(0.0, b)))
    y = np.zeros(grid_model.layout.size)
    y[grid_model.layout.speed] = 3.0
    cart, sc = kernel.pulls_of(grid_model.P, y, 0.0, 3.0, kernel.max_rate_of(grid_model.P))
    lateral = float(np.sum(cart[:, kernel.LAT]) + sc[kernel.FRONT_LAT])
    assert lateral == pytest.approx(sum(c.mass for c in tr.carts) * G * b, rel=1e-9)


def test_the_stance_on_a_grid_of_a_plane_is_the_surfaces_closed_form():
    """Roll asin(across / w), pitch -atan(along) at every cart (terrain.orientation), and the
    rollover margin 1 - 2 h tan(b) / t of a cart across a pure side slope b."""
    gx, gy = 0.08, -0.15
    tr = trains.train(3)
    carts = tuple(dataclasses.replace(c, track_width=2.5, com_height=1.2) for c in tr.carts)
    tr = on_grid(dataclasses.replace(tr, carts=carts), plane_grid(gx, gy))
    stance = Stance(tr)
    rng = np.random.default_rng(5)
    heading = rng.uniform(-math.pi, math.pi, (7, 3))
    a1 = (rng.uniform(-20, 20, 7), rng.uniform(-20, 20, 7))
    roll, pitch = stance.angles(heading, a1)
    for i in range(7):
        for k in range(3):
            expect = orientation(heading[i, k], tr.relief.at(0.0, 0.0))
            assert (roll[i, k], pitch[i, k]) == pytest.approx(expect, abs=1e-12)
    side = on_grid(tr, plane_grid(0.0, 0.3))
    margins = Stance(side).margins(np.zeros((1, 3)), (np.zeros(1), np.zeros(1)))
    assert margins[0] == pytest.approx(1.0 - 2.0 * 1.2 * 0.3 / 2.5, abs=1e-12)
    with pytest.raises(ValueError, match="A_1"):
        stance.angles(heading)


# -- energy: traction work = kinetic + potential + resistances ---------------------------------
def test_energy_balance_on_hills_with_the_potential_read_by_scipy():
    """Along a slalom over hills: the work of traction less the resistances' equals the change of
    the kinetic energy plus m g z(C_k), z read by scipy's spline (not by the kernel)."""
    tr = on_grid(trains.train(3), hills())
    model = Model(tr)
    z_of = RectBivariateSpline(tr.relief.ys, tr.relief.xs, tr.relief.heights, s=0)
    y0 = Simulation(trains.scene(tr, speed=2.5)).y

    def command(t):
        return 0.25 * math.sin(0.6 * t) + 0.1 * math.sin(1.7 * t)

    def energy(y):
        com = cart_points(tr, y[0], y[1], y[2:2 + tr.n])["C"]
        heights = [float(z_of(cy, cx)[0, 0]) for cx, cy in com]
        return model.kinetic_energy(y, 0.0, 3.0) + G * sum(c.mass * h for c, h in zip(tr.carts, heights))

    residual, rise, work, _ = trains.energy_balance(model, y0, command, energy)
    assert rise > 1e5  # the hills matter: J
    assert residual < 1e-8 * (rise + work + 1.0)


def test_the_kernel_is_the_readable_reference_on_a_grid():
    """The compiled y' equals the reference's (Model.terms through the plain-Python kernel
    functions) to the last bit, at random states on the hills."""
    tr = on_grid(trains.train(3), hills())
    model = Model(tr)
    rng = np.random.default_rng(11)
    for _ in range(20):
        y = trains.random_state(model, rng)
        y[0], y[1] = rng.uniform(-20, 120), rng.uniform(-60, 60)
        command, v_set = rng.uniform(-0.5, 0.5), rng.uniform(-3, 3)
        assert np.array_equal(model.rhs(0.0, y, command, v_set), model.derivative(y, command, v_set)[0])
        assert np.array_equal(kernel.rhs_of(model.P, y, command, v_set, kernel.max_rate_of(model.P)),
                              kernel.rhs_of.py_func(model.P, y, command, v_set, kernel.max_rate_of(model.P)))


def test_a_level_train_packs_no_relief():
    P = kernel.pack(trains.train(3))
    assert P[kernel.H.relief] == 0.0
    assert P.shape[0] == kernel.HEAD_SIZE + 3 * kernel.CART_SIZE + kernel.DRAFT_SIZE


# -- borders ---------------------------------------------------------------------------------
def test_a_train_leaving_the_grid_stops_the_run_naming_the_cart():
    tr = on_grid(trains.train(3), hills())
    sim, err = run_scene(trains.scene(tr, duration=200.0, speed=3.0))
    assert isinstance(err, ModelValidityError)
    assert "off the terrain" in str(err) and "'cart1'" in str(err) and "x in [-60, 172]" in str(err)
    kept = cart_points(tr, sim.y[0], sim.y[1], sim.y[2:5])["C"][0]  # the state before the failing tick
    assert 172.0 - 0.3 < kept[0] <= 172.0 and float(str(err).split("at (")[1].split(",")[0]) > 172.0


def test_levels_that_take_a_plane_only_refuse_a_grid_in_one_line():
    tr = on_grid(trains.train(3), hills())
    for name, algorithm in (("slip", 2), ("dynamic", 1)):
        with pytest.raises(ValueError) as err:
            make_level(name, tr, algorithm)
        assert "\n" not in str(err.value) and "height grid" in str(err.value)


def write_scene(folder, terrain: str, heights_text: str | None = "0,0,0,0\n" * 4,
                name: str = "h.csv") -> str:
    (folder / "train.yaml").write_text((CONFIG / "trains" / "hillside_unit.yaml").read_text())
    if heights_text is not None:
        (folder / name).write_text(heights_text)
    scene = folder / "scene.yaml"
    scene.write_text(f"train: train.yaml\nduration: 5\nspeed: 2.0\nsteering: {{maneuver: straight}}\n"
                     f"terrain: {terrain}\n")
    return str(scene)


@pytest.mark.parametrize("terrain, heights, words", [
    ("{heights: nowhere.csv, spacing: 5}", None, ["terrain", "nowhere.csv", "No such file"]),
    ("{heights: h.csv, spacing: 5}", "1,2,nan,4\n" * 4, ["heights", "nan at row 0, column 2", "finite"]),
    ("{heights: h.csv, spacing: 5}", "1\n", ["heights", "1 x 1 nodes", "at least 4 x 4"]),
    ("{heights: h.csv, spacing: 1}", "0,0,0,0\n0,0,0,0\n0,0,5,0\n0,0,0,0\n", ["a rise of 5 m over 1 m", "60 deg"]),
    ("{heights: h.csv, spacing: 5}", "0,0,0,0\n0,0,0\n0,0,0,0\n0,0,0,0\n", ["file", "a grid of numbers"]),
    ("{heights: h.csv}", "0,0,0,0\n" * 4, ["spacing", "(missing)", "must be given"]),
    ("{heights: h.csv, spacing: 5, origin: [1, 2, 3]}", "0,0,0,0\n" * 4, ["origin", "two numbers"]),
    ("{heights: h.csv, spacing: 5, grade_percent: 3}", "0,0,0,0\n" * 4, ["grade_percent", "not given with heights"]),
    ("{grade_percent: 3, spacing: 5}", None, ["spacing", "only with heights"]),
    ("{heights: h.csv, spacing: -5}", "0,0,0,0\n" * 4, ["spacing", "-5"]),
    ("{heights: h.csv, spacing: 1}", "0,0,0,0\n" * 4, ["initial", "centre of mass on the height grid", "tractor's"]),
])
def test_hostile_grids_in_a_scene_are_one_line(tmp_path, terrain, heights, words):
    path = write_scene(tmp_path, terrain, heights)
    before = sorted(p.name for p in tmp_path.iterdir())
    refused(path, words)
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def refused(path, words) -> None:
    """Loading the scene at ``path`` fails in one line holding every one of ``words``."""
    with pytest.raises(InputError) as err:
        loader.load_scene(path)
    message = str(err.value)
    assert "\n" not in message
    for word in words:
        assert word in message, message


def test_mta_check_refuses_a_hostile_grid_with_exit_code_2(tmp_path):
    path = write_scene(tmp_path, "{heights: h.csv, spacing: 5}", "inf,0,0,0\n" * 4)
    done = subprocess.run([sys.executable, "-m", "mta_sim_ros.cli", "check", path], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 2, done.stderr
    lines = [line for line in (done.stderr + done.stdout).splitlines() if line.strip()]
    assert len(lines) == 1 and "heights" in lines[0] and "finite" in lines[0]
    assert "Traceback" not in done.stderr


def test_the_hilly_field_replays_from_its_bag_without_the_grid_file(tmp_path):
    """The run's record holds the grid's heights: the scene read back from the bag has the same
    grid, and a record without them is refused in one line (no file is opened)."""
    from mta_sim_ros.node.runlog import recorded_scene

    scene = loader.load_scene(CONFIG / "scenes" / "hilly_field.yaml")
    meta = {"scene_file": scene.source, "scene_yaml": open(scene.source).read(), "train_file": scene.train.source,
            "train_yaml": open(scene.train.source).read(), "terrain_heights": scene.train.relief.as_text()}
    again = recorded_scene(meta, "run.mcap")
    np.testing.assert_array_equal(again.train.relief.heights, scene.train.relief.heights)
    assert np.array_equal(kernel.pack(again.train), kernel.pack(scene.train))
    del meta["terrain_heights"]
    with pytest.raises(InputError) as err:
        recorded_scene(meta, "run.mcap")
    assert "heights" in str(err.value) and "recorded" in str(err.value) and "\n" not in str(err.value)


def test_auto_fidelity_on_a_grid_keeps_the_dynamic_level_and_says_why():
    from mta_sim_ros.run.fidelity import choose

    scene = loader.load_scene(CONFIG / "scenes" / "hilly_field.yaml")
    auto = dataclasses.replace(scene, fidelity="auto", needs=dataclasses.replace(scene.needs or _needs(), power=1e-6))
    choice = choose(auto)
    assert choice.level == "dynamic" and "height grid" in choice.reason


def _needs():
    from mta_sim_ros.physics.spec import Needs

    return Needs()


# -- GeoTIFF (rasterio) -------------------------------------------------------------------------
def write_tiff(path, heights, crs="EPSG:32637", transform=None, nodata=None):
    """A GeoTIFF of ``heights`` (rows from the north, as a DEM is stored), written by rasterio."""
    import rasterio
    from affine import Affine

    transform = transform or Affine(8.0, 0.0, 400000.0, 0.0, -8.0, 5000200.0)  # 8 m pixels from the NW corner
    with rasterio.open(path, "w", driver="GTiff", height=heights.shape[0], width=heights.shape[1], count=1,
                       dtype="float64", crs=crs, transform=transform, nodata=nodata) as ds:
        ds.write(heights, 1)


def test_a_geotiff_is_the_same_grid_as_its_csv(tmp_path):
    """Pixels are nodes at their centres, rows turned to run along +y: a DEM written by rasterio
    loads as the grid of the same heights with the origin and spacing its transform says."""
    grid = hills(12, 10)
    north_first = grid.heights[::-1]
    write_tiff(tmp_path / "dem.tif", north_first)
    write_scene(tmp_path, "{heights: dem.tif}", heights_text=None)
    text = (tmp_path / "scene.yaml").read_text().replace("train: train.yaml", "train: train.yaml\n"
                                                         "initial: {x: 400040, y: 5000150}")
    (tmp_path / "scene.yaml").write_text(text)
    scene = loader.load_scene(tmp_path / "scene.yaml")
    relief = scene.train.relief
    np.testing.assert_array_equal(relief.heights, grid.heights)
    assert relief.origin == (400004.0, 5000200.0 - 8.0 * 9.5) and relief.spacing == 8.0
    from mta_sim_ros.node.runlog import recorded_scene, terrain_record

    meta = {"scene_file": scene.source, "scene_yaml": text, "train_file": scene.train.source,
            "train_yaml": open(scene.train.source).read(), **terrain_record(scene)}
    (tmp_path / "dem.tif").unlink()  # the record alone
    assert np.array_equal(kernel.pack(recorded_scene(meta, "run.mcap").train), kernel.pack(scene.train))


@pytest.mark.parametrize("options, terrain, words", [
    ({"crs": "EPSG:4326"}, "{heights: dem.tif}", ["EPSG:4326", "projected coordinate system in metres"]),
    ({"nodata": -9999.0}, "{heights: dem.tif}", ["nodata cell at row 2, column 3", "without nodata"]),
    ({"transform": (8.0, 0.5, 400000.0, 0.0, -8.0, 5000200.0)}, "{heights: dem.tif}", ["rotated", "north-up"]),
    ({"transform": (8.0, 0.0, 400000.0, 0.0, -10.0, 5000200.0)}, "{heights: dem.tif}", ["8 x 10 m", "square"]),
    ({}, "{heights: dem.tif, spacing: 8}", ["spacing", "GeoTIFF carries its own"]),
    ({"cell": np.nan}, "{heights: dem.tif}", ["nan at row 2, column 3 of", "finite numbers"]),  # the file's row
    ({"cell": 1e308}, "{heights: dem.tif}", ["1e+308 at row", "heights within +-100000 m"]),
])
def test_hostile_geotiffs_are_one_line(tmp_path, options, terrain, words):
    from affine import Affine

    heights = np.zeros((10, 12))
    options = dict(options)
    if "cell" in options:
        heights[2, 3] = options.pop("cell")
    if "nodata" in options:
        heights[2, 3] = options["nodata"]
    if "transform" in options:
        options = dict(options, transform=Affine(*options["transform"]))
    write_tiff(tmp_path / "dem.tif", heights, **options)
    refused(write_scene(tmp_path, terrain, heights_text=None), words)


def test_a_file_that_is_not_a_geotiff_is_one_line(tmp_path):
    (tmp_path / "dem.tif").write_bytes(b"II*\x00 not a tiff at all")
    path = write_scene(tmp_path, "{heights: dem.tif}", heights_text=None)
    with pytest.raises(InputError) as err:
        loader.load_scene(path)
    assert "a GeoTIFF GDAL reads" in str(err.value) and "\n" not in str(err.value)


def test_analyze_charts_power_against_the_grade_the_run_met(tmp_path):
    """From the bags alone: up the 12 % plane the grade met is 12 % at every pose; on the hilly
    field it is the grid's slope along the tractor at its centre of mass; power_grade.png is drawn."""
    from mta_sim_ros import cli
    from mta_sim_ros.analysis.bagdata import load_bag
    from mta_sim_ros.analysis.plots import grade_met

    for name, duration in (("hill_climb", "duration: 30"), ("hilly_field", "duration: 60")):
        text = (CONFIG / "scenes" / f"{name}.yaml").read_text().replace(duration, "duration: 4")
        text = text.replace("../", str(CONFIG.resolve()) + "/")
        (tmp_path / f"{name}.yaml").write_text(text)
        bag = tmp_path / f"{name}.mcap"
        assert cli.main(["run", "--scene", str(tmp_path / f"{name}.yaml"), "--bag", str(bag), "--quiet"]) == 0
        assert cli.main(["analyze", str(bag), "--out", str(tmp_path / name)]) == 0
        assert (tmp_path / name / "power_grade.png").stat().st_size > 0
        d = load_bag(bag)
        grade = grade_met(d)
        if name == "hill_climb":
            np.testing.assert_allclose(grade, 12.0, rtol=0, atol=1e-9)
        else:
            th = d.pose_heading.values[:, 0]
            com = d.poses.values[:, 0, :] - (d.train.carts[0].length - d.train.carts[0].com_offset) * np.stack(
                [np.cos(th), np.sin(th)], axis=1)
            ref = RectBivariateSpline(d.train.relief.ys, d.train.relief.xs, d.train.relief.heights, s=0)
            along = ref(com[:, 1], com[:, 0], dy=1, grid=False) * np.cos(th) + \
                ref(com[:, 1], com[:, 0], dx=1, grid=False) * np.sin(th)
            np.testing.assert_allclose(grade, 100.0 * along, rtol=0, atol=1e-6)
