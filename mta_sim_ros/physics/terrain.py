"""The ground under the train: a plane or a height grid, the surface's height and slope at any
point, a cart's roll and pitch on it, and its static rollover margin.

A plane is in the equations of motion (a scene's ``terrain``): the train moves in the plane, which
is the article's planar model exactly, with the model's x, y measured along the ground in the
plane's own frame (``PlaneFrame``) and gravity split into its component in the plane (a constant
vector: the grade resistance of every cart) and across it (the normal load: rolling resistance
scales with its cosine). A height grid is read and checked here but not yet in the equations.

Surface: ``z(x, y)`` in the frame of the train's plane (x, y the model's coordinates, z up), its
gradient ``G = (dz/dx, dz/dy)``. A plane has a constant G. A grid is a regular array of heights
(rows along y, columns along x, ``origin`` the (x, y) of heights[0, 0], ``spacing`` m between
nodes), interpolated by a bicubic spline through every node (scipy's RectBivariateSpline, s = 0):
heights, slopes and curvatures are continuous, as the slope terms of the equations need. A point
off the grid is :class:`OffTerrain`: nothing is extrapolated.

Orientation of a cart with heading ``th`` on a surface of gradient G (REP-103: x forward, y left,
z up; roll about x, positive left side up; pitch about y, positive nose down), with e = (cos th,
sin th), n = (-sin th, cos th), w = sqrt(1 + |G|^2):

    pitch = -atan(G . e)          roll = asin((G . n) / w)

Static rollover margin of a cart of track ``t`` and centre-of-mass height ``h`` (over the ground,
along its normal): the uphill wheels' share of the load over half of it. Gravity in the body frame
is -g (R20, R21, R22) (R world from body): its normal part g R22 presses the wheels, its lateral
part g R21 tips the cart about the downhill wheels' line (the body's x axis), and R21 / R22 is
tan(roll) whatever the pitch, so

    margin = 1 - 2 h |tan(roll)| / t

1 on the level, 0 where the uphill wheels lift (on a pure side slope b: tan b = t / (2 h)),
negative past it.

Longitudinal tip margin of the tractor (wheelbase L, centre of mass c ahead of the rear axle and h
over the ground, weight m g) towing with the drawbar pull P = H_2 . e_1 (the force on the drawbar
along the tractor's axis, kernel.drawbar_pulls) at the hitch height h_d, the cart behind resting
V_2 on the drawbar a_1 behind the rear axle (loads.hitch_loads: the chain's statics, normal to the
plane): its front axle's load over the load a lone tractor has standing on the level, from the
moments about the rear wheels' contact line (gravity along the body -g R20 at h, across it g R22 at
c, the pull parallel to the ground at h_d, V_2 across the ground at -a_1):

    N_f L = m g (R22 c - R20 h) - P h_d - V_2 a_1
    tip margin = R22 - R20 h / c - (P h_d + V_2 a_1) / (m g c)

1 for a lone tractor standing on the level, 0 where the front wheels lift (a lone tractor heading up a grade a:
tan a = c / h). Static: the tractor's own acceleration (m V' h more on the rear axle while it
speeds up) and the wheels' rolling moments are left out; the pull carries the carts' inertia.
"""
from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..validate import fail, show

#: the steepest slope a terrain may have anywhere (at a node of a grid), degrees: beyond it no
#: wheeled field machine stands, and the surface is more likely a unit error (cm read as m)
MAX_SLOPE_DEG = 60.0
#: the fewest nodes along each axis of a grid (a bicubic spline needs 4)
MIN_NODES = 4
#: the most nodes of a grid (16 M: 128 MB of float64), and the largest grid file read, bytes
MAX_NODES = 4096 * 4096
MAX_FILE_BYTES = 256 * 2**20
#: m: a height's, a grid origin's coordinates' and a node spacing's largest magnitude (Earth's relief spans
#: some 20 km, a projected coordinate some 1e7 m; a scene's positions take the same): beyond them the
#: spline's arithmetic overflows. A scene's origin and spacing are read by these rules (schema.py) too.
MAX_HEIGHT, MAX_COORDINATE, MIN_SPACING, MAX_SPACING = 1e5, 1e7, 0.01, 1e5


class OffTerrain(ValueError):
    """A point the terrain does not cover."""


@dataclass(frozen=True)
class Surface:
    """Height (m) and gradient (dz/dx, dz/dy) at a point."""

    z: float
    dzdx: float
    dzdy: float


@dataclass(frozen=True)
class Plane:
    """z = z0 + grade x + cross_slope y: grade and cross_slope are rises per metre (tan of the
    angles), along the model's x and y axes."""

    grade: float
    cross_slope: float
    z0: float = 0.0

    def at(self, x: float, y: float) -> Surface:
        return Surface(self.z0 + self.grade * x + self.cross_slope * y, self.grade, self.cross_slope)


@dataclass(frozen=True)
class PlaneFrame:
    """The frame of a plane the train moves in, in the world frame (REP-103, z up): unit vectors
    ``x`` (in the plane, over the world's x axis), ``y`` (in the plane, z cross x) and ``z`` (the
    plane's upward normal), each a 3-tuple; the plane passes through (0, 0, z0). The model's
    coordinates (u, v) are the point z0 + u x + v y: distances along the ground."""

    x: tuple[float, float, float]
    y: tuple[float, float, float]
    z: tuple[float, float, float]
    z0: float

    @classmethod
    def of(cls, plane: Plane) -> "PlaneFrame":
        gx, gy = plane.grade, plane.cross_slope
        w = math.sqrt(1.0 + gx * gx + gy * gy)
        r = math.sqrt(1.0 + gx * gx)
        ex = (1.0 / r, 0.0, gx / r)
        ez = (-gx / w, -gy / w, 1.0 / w)
        ey = (ez[1] * ex[2] - ez[2] * ex[1], ez[2] * ex[0] - ez[0] * ex[2], ez[0] * ex[1] - ez[1] * ex[0])
        return cls(ex, ey, ez, plane.z0)

    def gravity(self, g: float) -> tuple[float, float, float]:
        """Gravity (0, 0, -g) in this frame: (along x, along y, along the normal), m/s^2. The first
        two pull every mass along the ground; g cos(slope) = -third presses it on the ground."""
        return -g * self.x[2], -g * self.y[2], -g * self.z[2]

    def point(self, u: float, v: float, height: float = 0.0) -> tuple[float, float, float]:
        """The world position of the model's point (u, v), ``height`` above the plane along its normal."""
        return tuple(u * a + v * b + height * c + (self.z0 if i == 2 else 0.0)
                     for i, (a, b, c) in enumerate(zip(self.x, self.y, self.z)))

    def rotation(self, heading: float) -> np.ndarray:
        """The 3 x 3 rotation (world from body) of a body on the plane with heading ``heading`` in
        the plane's frame: [x y z] Rz(heading)."""
        c, s = math.cos(heading), math.sin(heading)
        frame = np.array([self.x, self.y, self.z]).T
        return frame @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    def quaternion(self, heading: float) -> tuple[float, float, float, float]:
        """(x, y, z, w) of ``rotation(heading)``, w >= 0."""
        return quaternion_of(self.rotation(heading))

    def roll_pitch(self, heading: float) -> tuple[float, float]:
        """(roll, pitch), rad, REP-103 (roll about the body's x, left side up > 0; pitch about its
        y, nose down > 0) of a body with this heading on the plane."""
        R = self.rotation(heading)
        return math.atan2(R[2, 1], R[2, 2]), -math.asin(max(-1.0, min(1.0, R[2, 0])))


def quaternion_of(R: np.ndarray) -> tuple[float, float, float, float]:
    """(x, y, z, w), w >= 0, of a rotation matrix (Shepperd's method: the largest of the four
    squares first, so no division by a small number)."""
    t = R[0, 0] + R[1, 1] + R[2, 2]
    if t > max(R[0, 0], R[1, 1], R[2, 2]):
        w = 0.5 * math.sqrt(1.0 + t)
        q = ((R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w), (R[1, 0] - R[0, 1]) / (4 * w), w)
    else:
        i = int(np.argmax([R[0, 0], R[1, 1], R[2, 2]]))
        j, k = (i + 1) % 3, (i + 2) % 3
        a = 0.5 * math.sqrt(max(0.0, 1.0 + R[i, i] - R[j, j] - R[k, k]))
        q = [0.0, 0.0, 0.0, (R[k, j] - R[j, k]) / (4 * a)]
        q[i], q[j], q[k] = a, (R[j, i] + R[i, j]) / (4 * a), (R[k, i] + R[i, k]) / (4 * a)
        q = tuple(q)
    return q if q[3] >= 0 else tuple(-v for v in q)


class Stance:
    """Each cart's roll and pitch on the train's ground and its static rollover margin (the carts
    with track_width and com_height), and the tractor's tip margin with the drawbar pull besides.
    On a plane they follow from the headings alone: with F the plane's frame, a body of heading th
    has R = F Rz(th), so R[2, 0] = F20 cos th + F21 sin th, R[2, 1] = F21 cos th - F20 sin th,
    R[2, 2] = F22 (``PlaneFrame.roll_pitch``, vectorised). On a height grid each cart stands on the
    surface at its centre of mass C_k (placed from A_1, ``a1``, back along the headings), of
    gradient G: with along = G . e, across = G . n, w = sqrt(1 + |G|^2),
    R20 = along / sqrt(1 + along^2), R21 = across / (w sqrt(1 + along^2)), R22 = 1 / w
    (``orientation``)."""

    def __init__(self, train):
        frame = PlaneFrame.of(train.terrain) if train.terrain is not None else PlaneFrame.of(Plane(0.0, 0.0))
        self.relief = train.relief
        self.level = train.terrain is None and train.relief is None
        self.f20, self.f21, self.f22 = frame.x[2], frame.y[2], frame.z[2]
        self.names = [c.name for c in train.carts]
        self.measured = np.array([c.track_width is not None for c in train.carts])
        self.track = np.array([c.track_width or 1.0 for c in train.carts])
        self.height = np.array([c.com_height or 0.0 for c in train.carts])
        #: A_k to C_k and A_k to A_{k+1} along e_k, m (a height grid's C_k, ``centres``)
        self.to_com = np.array([c.length - c.com_offset for c in train.carts])
        self.to_next = np.array([c.length + c.hitch_offset for c in train.carts])
        from .loads import hitch_loads  # (loads.py reads this module's PlaneFrame)

        tractor = train.carts[0]
        self.tows = len(train.carts) > 1
        known = tractor.com_height is not None and tractor.com_offset > 0 and (tractor.hitch_height or not self.tows)
        #: (c, h, h_d, m g, V_2 a_1) of the tractor's tip margin, or None where it is not known (``tip_margins``)
        self.tip = (tractor.com_offset, tractor.com_height, tractor.hitch_height or 0.0, tractor.mass * train.gravity,
                    float(hitch_loads(train)[1]) * tractor.hitch_offset) if known else None

    def centres(self, heading, a1) -> tuple[np.ndarray, np.ndarray]:
        """(x, y) of every cart's C_k (rows x carts) from A_1 = ``a1`` ((x, y), each a number or
        rows) and the headings (rows x carts)."""
        th = np.asarray(heading, dtype=float)
        ex, ey = np.cos(th), np.sin(th)
        ax = np.asarray(a1[0], dtype=float)[..., None] - np.cumsum(self.to_next * ex, axis=-1) + self.to_next * ex
        ay = np.asarray(a1[1], dtype=float)[..., None] - np.cumsum(self.to_next * ey, axis=-1) + self.to_next * ey
        return ax - self.to_com * ex, ay - self.to_com * ey

    def rotation_rows(self, heading, a1=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(R20, R21, R22) of every cart (the class docstring); ``a1`` is needed on a height grid."""
        th = np.asarray(heading, dtype=float)
        c, s = np.cos(th), np.sin(th)
        if self.relief is None:
            return self.f20 * c + self.f21 * s, self.f21 * c - self.f20 * s, np.full(th.shape, self.f22)
        if a1 is None:
            raise ValueError("Stance on a height grid needs the position of A_1")
        from .kernel import surfaces_of

        cx, cy = self.centres(th, a1)
        _, gx, gy = (v.reshape(cx.shape) for v in surfaces_of(self.relief.block, cx.ravel(), cy.ravel()))
        along, across = gx * c + gy * s, gy * c - gx * s
        w, u = np.sqrt(1.0 + gx * gx + gy * gy), np.sqrt(1.0 + along * along)
        return along / u, across / (w * u), 1.0 / w

    def angles(self, heading, a1=None) -> tuple[np.ndarray, np.ndarray]:
        """(roll, pitch) of every cart, rad (REP-103)."""
        r20, r21, r22 = self.rotation_rows(heading, a1)
        return np.arctan2(r21, r22), -np.arcsin(np.clip(r20, -1.0, 1.0))

    def margins(self, heading, a1=None) -> np.ndarray:
        """The static rollover margin of every cart (NaN where track and height are not given)."""
        roll, pitch = self.angles(heading, a1)
        m = 1.0 - 2.0 * self.height * np.abs(np.tan(roll)) / self.track
        return np.where(self.measured, m, np.nan)

    def tip_margins(self, heading, pull, a1=None) -> np.ndarray:
        """The tractor's longitudinal tip margin (``tip_margin``) at each row of ``heading`` (rows x
        carts) with the drawbar pull ``pull`` along its axis (rows, N); NaN where it is not known: the
        tractor gives no com_height, or tows and gives no hitch_height, or its centre of mass is not
        ahead of its rear axle (c <= 0), or it tows and the pull is NaN (a level without constraint
        forces; a lone tractor's is 0)."""
        th = np.asarray(heading)[..., 0]
        if self.tip is None:
            return np.full(np.shape(th), np.nan)
        pull = np.asarray(pull, dtype=float) if self.tows else np.zeros(np.shape(th))
        r20, _, r22 = self.rotation_rows(np.asarray(heading)[..., :1], a1)
        return tip_margin(*self.tip, r20[..., 0], r22[..., 0], pull)


class HeightGrid:
    """A regular grid of heights (rows along y), interpolated by a bicubic spline through every
    node (scipy's RectBivariateSpline, s = 0, fits it; kernel/relief.py evaluates it, in the
    equations and here alike). Built from checked arrays only: :func:`grid_from` checks them."""

    def __init__(self, heights: np.ndarray, origin: tuple[float, float], spacing: float, source: str = "",
                 file: str = ""):
        from scipy.interpolate import RectBivariateSpline

        self.heights = heights
        #: source: the scene that names the grid; file: the heights' own file ('' when a run recorded them)
        self.origin, self.spacing, self.source, self.file = origin, spacing, source, file
        ny, nx = heights.shape
        self.xs = origin[0] + spacing * np.arange(nx)
        self.ys = origin[1] + spacing * np.arange(ny)
        ty, tx, coefficients = RectBivariateSpline(self.ys, self.xs, heights, kx=3, ky=3, s=0).tck
        #: (knots along y, knots along x, coefficients rows along y, flat): what the kernel packs
        self.spline = (ty, tx, coefficients)
        self.block = np.concatenate(([len(ty), len(tx)], ty, tx, coefficients)).astype(np.float64)

    def covers(self, x: float, y: float) -> bool:
        return bool(self.xs[0] <= x <= self.xs[-1] and self.ys[0] <= y <= self.ys[-1])

    def at(self, x: float, y: float) -> Surface:
        if not self.covers(x, y):
            raise OffTerrain(f"({x:.3f}, {y:.3f}) m is off the terrain grid x in [{self.xs[0]:g}, {self.xs[-1]:g}], "
                             f"y in [{self.ys[0]:g}, {self.ys[-1]:g}] m")
        from .kernel import surface_of

        return Surface(*surface_of(self.block, float(x), float(y)))

    def as_text(self) -> str:
        """The heights as CSV text (every digit: a run's record, ``heights_from_text`` reads it)."""
        return "\n".join(",".join(repr(float(v)) for v in row) for row in self.heights) + "\n"

    def __repr__(self) -> str:
        ny, nx = self.heights.shape
        return f"HeightGrid({ny} x {nx} nodes, origin {self.origin}, spacing {self.spacing:g} m)"


def orientation(heading: float, surface: Surface) -> tuple[float, float]:
    """(roll, pitch), rad, of a cart whose horizontal heading is ``heading`` on ``surface``
    (the module docstring)."""
    c, s = math.cos(heading), math.sin(heading)
    along = surface.dzdx * c + surface.dzdy * s
    across = -surface.dzdx * s + surface.dzdy * c
    w = math.sqrt(1.0 + surface.dzdx ** 2 + surface.dzdy ** 2)
    return math.asin(across / w), -math.atan(along)


def rollover_margin(track: float, com_height: float, roll: float) -> float:
    """The static rollover margin (the module docstring): 1 level, 0 at the tipping slope."""
    return 1.0 - 2.0 * com_height * abs(math.tan(roll)) / track


def tip_margin(com_offset: float, com_height: float, hitch_height: float, weight: float, drawbar_moment: float,
               r20, r22, pull):
    """The tractor's longitudinal tip margin (the module docstring) from R20, R22 of its rotation,
    the pull along its axis, N, its weight m g, N, and V_2 a_1, N m (numbers or arrays)."""
    return r22 - r20 * com_height / com_offset - (pull * hitch_height + drawbar_moment) / (weight * com_offset)


def tipping_side_slope(track: float, com_height: float) -> float:
    """The side slope, rad, where the margin reaches 0: atan(t / (2 h))."""
    return math.atan(track / (2.0 * com_height))


# -- reading and checking ---------------------------------------------------------------------------

def plane_from(grade_percent: float, cross_slope_percent: float, where: str = "terrain", source: str = "") -> Plane:
    """A plane from its grades in percent (rise per 100 m), the steepest within MAX_SLOPE_DEG."""
    for name, value in (("grade_percent", grade_percent), ("cross_slope_percent", cross_slope_percent)):
        if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value):
            fail(name, show(value), "a finite number (percent)", where, source)
    plane = Plane(grade_percent / 100.0, cross_slope_percent / 100.0)
    steepest = math.degrees(math.atan(math.hypot(plane.grade, plane.cross_slope)))
    if steepest > MAX_SLOPE_DEG:
        fail("grade_percent", f"{grade_percent:g} with cross_slope_percent {cross_slope_percent:g}",
             f"a slope of at most {MAX_SLOPE_DEG:g} deg (this is {steepest:.1f} deg)", where, source)
    return plane


def grid_from(heights: object, origin: object, spacing: object, where: str = "terrain", source: str = "",
              file: str = "") -> HeightGrid:
    """A HeightGrid from a 2-D array of heights (m), the (x, y) of its first node and the node
    spacing (m), checked: finite numbers, at least MIN_NODES nodes along each axis, at most
    MAX_NODES in all, no slope between neighbouring nodes over MAX_SLOPE_DEG."""
    if not (isinstance(spacing, (int, float)) and not isinstance(spacing, bool) and
            MIN_SPACING <= spacing <= MAX_SPACING):
        fail("spacing", show(spacing), f"in [{MIN_SPACING:g}, {MAX_SPACING:g}] m (between nodes)", where, source)
    if not (isinstance(origin, (list, tuple)) and len(origin) == 2
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) and abs(v) <= MAX_COORDINATE
                    for v in origin)):
        fail("origin", show(origin), f"[x, y] of the first node, two numbers within +-{MAX_COORDINATE:g} m", where,
             source)
    h = np.asarray(heights)
    if h.ndim != 2 or h.dtype.kind not in "iuf":
        fail("heights", f"an array of shape {h.shape} ({h.dtype})", "a 2-D array of numbers (rows along y)", where,
             source)
    if min(h.shape) < MIN_NODES:
        fail("heights", f"{h.shape[0]} x {h.shape[1]} nodes", f"at least {MIN_NODES} x {MIN_NODES} (a bicubic "
             "surface)", where, source)
    if h.size > MAX_NODES:
        fail("heights", f"{h.shape[0]} x {h.shape[1]} nodes", f"at most {MAX_NODES} nodes", where, source)
    h = h.astype(np.float64)
    bad = np.argwhere(~np.isfinite(h))
    if bad.size:
        row, col = bad[0]
        fail("heights", f"{h[row, col]} at row {row}, column {col}", "finite numbers (m)", where, source)
    highest = float(np.max(np.abs(h)))
    if highest > MAX_HEIGHT:
        row, col = np.unravel_index(int(np.argmax(np.abs(h))), h.shape)
        fail("heights", f"{h[row, col]:g} at row {row}, column {col}", f"heights within +-{MAX_HEIGHT:g} m", where,
             source)
    steepest = max(float(np.max(np.abs(np.diff(h, axis=a)), initial=0.0)) for a in (0, 1)) / float(spacing)
    if math.degrees(math.atan(steepest)) > MAX_SLOPE_DEG:
        fail("heights", f"a rise of {steepest * spacing:g} m over {spacing:g} m between neighbouring nodes",
             f"a slope of at most {MAX_SLOPE_DEG:g} deg", where, source)
    return HeightGrid(h, (float(origin[0]), float(origin[1])), float(spacing), source, file)


def read_heights(path: str | os.PathLike, where: str = "terrain", source: str = "") -> np.ndarray:
    """The heights of a grid file: .npy (numpy's format, no pickles) or .csv (one row of the grid
    a line, comma-separated, every row as long), at most MAX_FILE_BYTES."""
    p = Path(path)
    try:
        size = p.stat().st_size
    except OSError as err:
        fail("file", show(str(path)), f"a readable grid file ({err.strerror or err})", where, source)
    if not p.is_file():
        fail("file", show(str(path)), "a file (.npy, .csv or a GeoTIFF .tif)", where, source)
    if size > MAX_FILE_BYTES:
        fail("file", f"{show(str(path))} of {size} bytes", f"at most {MAX_FILE_BYTES} bytes", where, source)
    suffix = p.suffix.lower()
    try:
        if suffix == ".npy":
            return np.load(p, allow_pickle=False)
        if suffix == ".csv":
            with warnings.catch_warnings():  # an empty file: grid_from says so, in its one line
                warnings.simplefilter("ignore", UserWarning)
                return np.loadtxt(p, delimiter=",", ndmin=2, encoding="utf-8-sig")  # a spreadsheet's BOM
    except (ValueError, OSError, EOFError) as err:
        fail("file", show(str(path)), f"a grid of numbers ({str(err).splitlines()[0] if str(err) else err!r})",
             where, source)
    fail("file", show(str(path)), "a .npy or .csv grid of heights, or a GeoTIFF (.tif)", where, source)


def heights_from_text(text: str, where: str = "terrain", source: str = "") -> np.ndarray:
    """The heights of CSV text (a run's record of its grid, ``HeightGrid.as_text``)."""
    import io

    if not isinstance(text, str) or len(text) > MAX_FILE_BYTES:
        fail("heights", "the recorded grid", f"CSV text of at most {MAX_FILE_BYTES} bytes", where, source)
    try:
        return np.loadtxt(io.StringIO(text), delimiter=",", ndmin=2)
    except ValueError as err:
        fail("heights", "the recorded grid", f"a grid of numbers ({str(err).splitlines()[0] if str(err) else err!r})",
             where, source)


def heading_of(x: float, y: float, z: float, w: float) -> float:
    """The horizontal heading, rad, of a body whose orientation is the quaternion (x, y, z, w): the
    direction of its x axis projected on the level, atan2(R10, R00); a turn about z alone gives
    2 atan2(z, w) exactly (the level's and a plane's poses), a pose on a height grid its yaw."""
    if x == 0.0 and y == 0.0:
        return 2.0 * math.atan2(z, w)
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
