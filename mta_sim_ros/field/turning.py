"""How tightly the train turns and how far it reaches into the headland: what every turn of a plan
is sized from (the model's own kinematic chain, inverted along a candidate turn, not a guess).

The working point P is the implement's: cart m = ``train.implement.cart``, ``d`` = its offset from
the axle B_m forward along the cart's axis. The plan's turns are continuous-curvature (CC) turns
(clothoid.py): P's path has a smallest radius R and a sharpness sigma (dkappa/ds; clothoids of
L = 1 / (R sigma) from straight to R). They are chosen so the train can follow them:

- the **guard**: forward, the controller holds the steering to the one whose steady circle keeps
  every hitch GUARD_MARGIN (10 deg) from its jackknife limits (``guarded_steering``); held there
  the train settles on that circle, so no command folds it;
- a candidate (R, L) is **followable** when the steering the kinematic chain asks along the
  narrowest U of it (a CC half turn between straights; physics/kernel/inverse.py, the inverse
  the controller's feedforward is), psi_ref(s), stays STEERING_ROOM below the guard (the room
  the tracking correction needs), its rate V dpsi_ref/ds at TURN_SPEED within RATE_SHARE of the
  actuator's max_rate, and every hitch angle HITCH_MARGIN from the cart's max_hitch_angle;
- of the followable ones the plan takes the one whose narrowest U is the narrowest: for each L in
  CLOTHOIDS the smallest followable R by bisection (the demands fall as R grows), then the L whose
  CC half turn is narrowest.

The inverse, not a simulated drive, because it is what the controller feeds forward: a turn
whose feedforward stays inside the guard is driven on its line, up to the feedback's small
corrections, and it costs a fraction of a millisecond a candidate (a drive of the candidate would
also measure the feedback, but cost a compile and seconds per candidate).

The reach is measured on the same inverse: every cart's pose along the narrowest U and along a U
of two quarter turns, the largest distance any corner of any cart's box (``physics.outline.box_of``)
gets beyond the swath's end, along the swath.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..physics.kernel.inverse import inverse_of
from ..physics.kernel.packing import pack
from ..physics.outline import box_of
from ..physics.steady import SteadyStateError, steady_circle
from ..validate import fail
from .boundary import FieldError
from .clothoid import Curves, bulb_moves, cc_turn, min_u, quarter, u_moves, wider_radius
from .route import Move, Pose, moves_stretch

#: share of the actuator's max_angle a planned turn may use
STEERING_SHARE = 0.8
#: rad: what every hitch keeps to its max_hitch_angle along a planned turn (20 deg)
HITCH_MARGIN = math.radians(20.0)
#: rad: forward, the controller holds the steering to the steady circle this far from every
#: jackknife limit (controllers/implement/design.py's Settings.hitch_margin)
GUARD_MARGIN = math.radians(10.0)
#: rad: the feedforward of a planned turn stays this far below the guard (the feedback's room)
STEERING_ROOM = math.radians(2.0)
#: m/s: the speed turns are driven at (design.py's Settings.turn_speed)
TURN_SPEED = 2.0
#: share of the actuator's max_rate the feedforward of a planned turn may ask
RATE_SHARE = 0.5
#: m: the clothoid lengths tried
CLOTHOIDS = (1.0, 2.0, 3.0, 4.0, 6.0, 8.0, 10.0, 12.0, 13.0, 14.0, 15.0, 16.0, 18.0, 20.0, 25.0, 30.0)
#: m: sampling of a candidate turn
CHECK_SPACING = 0.25
#: bisection steps on the radius
BISECTIONS = 14


@dataclass(frozen=True)
class Turning:
    """The train's planned turns: the smallest radius and the sharpness, and what they ask."""

    radius: float  # R, m: the working point's smallest radius
    sharpness: float  # sigma, 1/m^2
    min_u: float  # m: the narrowest U-turn's width (a CC half turn at R)
    steering: float  # rad: the largest steering the narrowest U's feedforward asks
    rate: float  # rad/s: its largest rate at TURN_SPEED
    margin: float  # rad: the smallest margin of a hitch to its max_hitch_angle along it (inf: none)
    guard: float  # rad: the controller's forward guard (GUARD_MARGIN)
    steady: float  # m: P's steady radius at the guard less STEERING_ROOM (no turn is tighter)
    bound: str  # what limits R and sigma, in words
    cart: int  # m, index of the implement's cart
    offset: float  # d, m

    @property
    def curves(self) -> Curves:
        return Curves(self.radius, self.sharpness)

    @property
    def clothoid(self) -> float:
        return self.curves.clothoid


@dataclass(frozen=True)
class Reach:
    """How far a planned U-turn reaches beyond the swath's end (the chain's poses along it)."""

    train: float  # m: the farthest outline corner beyond the working point's start, along the swath
    point: float  # m: the working point's own farthest
    speed: float  # m/s the check assumed (TURN_SPEED)


@dataclass(frozen=True)
class Demand:
    """What the inverse chain asks along a path (``demand``)."""

    steering: float  # rad, largest |psi_ref|
    rate: float  # rad/s, largest |dpsi_ref/dt| at the speed
    margin: float  # rad, smallest max_hitch_angle - |phi_k|
    axle: np.ndarray  # (m, n, 2) B_k
    heading: np.ndarray  # (m, n) th_k
    xy: np.ndarray  # (m, 2) the path


def implement_of(train) -> tuple[int, float, float]:
    """(cart index m, offset d, width) of the train's implement; FieldError if it has none."""
    if train.implement is None:
        fail("implement", "(missing)", "given: the working tool (cart, width, offset) a field plan is made for",
             "train", train.source or train.name, FieldError)
    tool = train.implement
    return train.cart_index(tool.cart), float(tool.offset), float(tool.width)


def margin_at(train, steering: float) -> float:
    """The smallest jackknife margin of the steady circle at ``steering`` (rad; inf for one cart),
    or -inf where no steady circle exists."""
    try:
        circle = steady_circle(train, steering)
    except SteadyStateError:
        return -math.inf
    margins = [min(cart.max_hitch_angle - abs(phi), math.pi / 2 - abs(psi))
               for cart, phi, psi in zip(train.carts[1:], circle.hitch_angles, circle.psi[1:])]
    return min(margins, default=math.inf)


def guarded_steering(train, margin: float = GUARD_MARGIN) -> float:
    """The largest steering (<= max_angle) whose steady circle keeps every hitch ``margin`` from
    its jackknife limits (``margin_at``; bisection: the margin falls as the steering grows).
    Forward, a train held at it settles on that circle: no command beyond it can fold the train."""
    top = train.actuator.max_angle
    if margin_at(train, top) >= margin:
        return top
    low, high = 0.0, top
    for _ in range(60):
        mid = 0.5 * (low + high)
        low, high = (mid, high) if margin_at(train, mid) >= margin else (low, mid)
    return low


def check_path(curves: Curves, lead: float, moves=None) -> np.ndarray:
    """(m, 3) x, y, heading of a straight of ``lead``, ``moves`` (default: the narrowest U, a CC
    half turn at ``curves``) and a straight of ``lead``, sampled at CHECK_SPACING."""
    turn = cc_turn(math.pi, curves) if moves is None else moves
    stretches = moves_stretch("turn", Pose(-lead, 0.0, 0.0), [Move(lead), *turn, Move(lead)],
                              spacing=CHECK_SPACING)
    st = stretches[0]
    return np.column_stack([st.xy, st.heading])


def demand(train, path: np.ndarray, speed: float = TURN_SPEED, P=None) -> Demand:
    """The inverse chain along ``path`` (m, 3) driven forwards (module docstring), and every
    cart's pose."""
    m, d, _ = implement_of(train)
    P = pack(train) if P is None else P
    count = path.shape[0]
    zeros = np.zeros(count)
    end = np.full(count, count - 1.0)
    ref = inverse_of(P, np.ascontiguousarray(path[:, 0]), np.ascontiguousarray(path[:, 1]),
                     np.ascontiguousarray(path[:, 2]), zeros, end, m, d)
    n = train.n
    psi = ref[:, n]
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(path[:, :2], axis=0).T))])
    rate = np.abs(np.diff(psi) / np.diff(s)) * speed
    heading = np.empty((count, n))
    heading[:, 0] = ref[:, 0] + path[:, 2]
    for k in range(1, n):
        heading[:, k] = heading[:, k - 1] - ref[:, k]
    margins = [train.carts[k].max_hitch_angle - np.abs(ref[:, k]).max() for k in range(1, n)]
    return Demand(float(np.abs(psi).max()), float(rate.max()), min(margins, default=math.inf),
                  chain_axles(train, path[:, :2], heading, m, d), heading, path[:, :2])


def chain_axles(train, point: np.ndarray, heading: np.ndarray, m: int, d: float) -> np.ndarray:
    """(count, n, 2): every axle B_k, given the working point of cart m and every heading."""
    e = np.stack([np.cos(heading), np.sin(heading)], axis=-1)
    axle = np.empty(heading.shape + (2,))
    axle[:, m] = point - d * e[:, m]
    for k in range(m - 1, -1, -1):  # B_k = A_{k+1} + a_k e_k, A_{k+1} = B_{k+1} + l_{k+1} e_{k+1}
        axle[:, k] = axle[:, k + 1] + train.carts[k + 1].length * e[:, k + 1] + train.carts[k].hitch_offset * e[:, k]
    for k in range(m + 1, train.n):  # A_k = B_{k-1} - a_{k-1} e_{k-1}, B_k = A_k - l_k e_k
        axle[:, k] = axle[:, k - 1] - train.carts[k - 1].hitch_offset * e[:, k - 1] - train.carts[k].length * e[:, k]
    return axle


def followable(found: Demand, limit: float, max_rate: float, slack: float = 0.0) -> bool:
    """Within the limits (module docstring); ``slack``: a share they may be passed by (a shape
    checked after R and sigma were bisected to the limits: one entering the same way may ask a
    hair more)."""
    return (found.steering <= limit * (1.0 + slack) and found.rate <= RATE_SHARE * max_rate * (1.0 + slack)
            and found.margin >= HITCH_MARGIN)


#: the share a shape checked after the bisection may pass the limits by (0.1 deg of 17.6 deg)
SLACK = 0.006


def lead_length(train) -> float:
    """m of straight before and after a checked turn: three train lengths, so the chain's transients
    (each decaying over a cart's length) are gone at both ends."""
    return 3.0 * sum(c.length + abs(c.hitch_offset) for c in train.carts)


def steady_radius(train, steering: float, m: int, d: float) -> float:
    return math.hypot(steady_circle(train, steering).R_B[m], d)


def candidates(train, limit: float, P, lead: float, speed: float = TURN_SPEED, floor: float = 0.0,
               angle: float = math.pi):
    """[(Curves, narrowest U)]: for each clothoid length of CLOTHOIDS, the smallest R (at least
    ``floor``) whose CC turn of ``angle`` the train follows at ``speed``."""
    max_rate = train.actuator.max_rate
    m, d, _ = implement_of(train)
    floor = max(floor, steady_radius(train, limit, m, d))
    out = []
    for length in CLOTHOIDS:
        def ok(radius: float) -> bool:
            curves = Curves(radius, 1.0 / (radius * length))
            moves = cc_turn(angle, curves)
            return followable(demand(train, check_path(curves, lead, moves), speed, P), limit, max_rate)

        if ok(floor):
            out.append((Curves(floor, 1.0 / (floor * length)), min_u(Curves(floor, 1.0 / (floor * length)))))
            continue
        low, high = floor, 2.0 * floor
        while not ok(high):
            low, high = high, 2.0 * high
            if high > 1e3:
                break
        else:
            for _ in range(BISECTIONS):
                mid = 0.5 * (low + high)
                low, high = (mid, high) if not ok(mid) else (low, mid)
            curves = Curves(high, 1.0 / (high * length))
            out.append((curves, min_u(curves)))
    return out


def turning(train, spacing: float | None = None) -> Turning:
    """The train's planned turns (module docstring): of the followable candidates, the one whose
    narrowest U fits the fewest ``spacing`` s (swath spacings; None: the narrowest U), then the
    one reaching least beyond the swath's end."""
    m, d, _ = implement_of(train)
    guard = guarded_steering(train)
    limit = min(guard - STEERING_ROOM, STEERING_SHARE * train.actuator.max_angle)
    if limit <= 0.0 and guard >= train.actuator.max_angle * (1.0 - 1e-9):  # the lock itself binds, not the hitches
        fail("max_angle_deg", f"{math.degrees(train.actuator.max_angle):g}",
             f"a steering lock that leaves a planned turn room: its feedforward asks at most {STEERING_SHARE:g} of "
             f"the lock and keeps {math.degrees(STEERING_ROOM):g} deg inside the guard's "
             f"{math.degrees(guard):.3g} deg", "actuator", train.source or train.name, FieldError)
    if limit <= 0.0 or margin_at(train, 1e-6) < GUARD_MARGIN:
        fail("max_hitch_angle", "too small", f"more than {math.degrees(HITCH_MARGIN):g} deg on every hitch "
             "(a planned turn keeps that margin to the jackknife limits)", "train", train.source or train.name,
             FieldError)
    P, lead = pack(train), lead_length(train)
    found = candidates(train, limit, P, lead)
    if not found:
        fail("train", train.name, "able to follow a continuous-curvature U-turn of at most 1 km radius", "",
             train.source, FieldError)

    def key(item):
        curves, width = item
        spans = math.ceil(width / spacing * (1.0 - 1e-9)) if spacing else width
        return spans, reach_of(train, demand(train, check_path(curves, lead), P=P))[0], width

    curves, width = min(found, key=key)
    check = demand(train, check_path(curves, lead), P=P)
    bound = (f"the feedforward {math.degrees(STEERING_ROOM):g} deg inside the guard "
             f"{math.degrees(guard):.3g} deg, its rate within {RATE_SHARE:.0%} of {train.actuator.max_rate:g} rad/s "
             f"at {TURN_SPEED:g} m/s, every hitch {math.degrees(HITCH_MARGIN):g} deg from its limit")
    return Turning(curves.radius, curves.sharpness, width, check.steering, check.rate, check.margin, guard,
                   steady_radius(train, limit, m, d), bound, m, d)


def ring_curves(train, turn: Turning, speed: float) -> Curves:
    """The headland rings' corners: of the CC turns with R >= the turns' own that the train follows
    at the working ``speed`` in a quarter turn (the same limits; the rate grows with the speed), the
    one whose quarter turn cuts a corner least (the smallest tangent length T)."""
    limit = min(turn.guard - STEERING_ROOM, STEERING_SHARE * train.actuator.max_angle)
    found = candidates(train, limit, pack(train), lead_length(train), speed, turn.radius, 0.5 * math.pi)
    if not found:
        return turn.curves
    return min((c for c, _ in found), key=quarter)


def min_straight(train, turn: Turning, curves: Curves, speed: float) -> float:
    """m: the shortest straight between two CC quarter turns of ``curves`` the same way that the
    train follows at ``speed`` (the chain, ~15 m long, is in the second turn while its carts still
    come out of the first: close corners ask more than one); bisection, 0.1 m."""
    limit = min(turn.guard - STEERING_ROOM, STEERING_SHARE * train.actuator.max_angle)
    P, lead = pack(train), lead_length(train)

    def ok(straight: float) -> bool:
        moves = [*cc_turn(0.5 * math.pi, curves), Move(straight), *cc_turn(0.5 * math.pi, curves)]
        return followable(demand(train, check_path(curves, lead, moves), speed, P), limit, train.actuator.max_rate,
                          SLACK)

    low, high = 0.0, lead
    if ok(low):
        return 0.0
    while high - low > 0.1:
        mid = 0.5 * (low + high)
        low, high = (mid, high) if not ok(mid) else (low, mid)
    return high


def corners(train, axle: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """(..., n * 4, 2) the corners of every cart's box with axles B_k ``axle`` (..., n, 2), headings
    (..., n)."""
    out = []
    for k in range(train.n):
        centre, length, width, _ = box_of(train, k)
        e = np.stack([np.cos(heading[..., k]), np.sin(heading[..., k])], axis=-1)
        n = np.stack([-e[..., 1], e[..., 0]], axis=-1)
        for along in (centre + length / 2, centre - length / 2):
            for across in (width / 2, -width / 2):
                out.append(axle[..., k, :] + along * e + across * n)
    return np.stack(out, axis=-2)


def reach_of(train, found: Demand) -> tuple[float, float]:
    """(outline, working point): the farthest beyond x = 0 along a checked path."""
    outline = float(corners(train, found.axle, found.heading)[..., 0].max())
    return outline, float(found.xy[:, 0].max())


def turn_reach(train, turn: Turning) -> Reach:
    """How far the train reaches beyond a swath's end in the narrowest U and in a U of two quarter
    turns (module docstring): every cart's pose along the inverse chain."""
    lead = lead_length(train)
    curves = turn.curves
    out = []
    for moves in (None, u_moves(2.0 * quarter(curves), curves)):
        found = demand(train, check_path(curves, lead, moves))
        out.append(reach_of(train, found))
    return Reach(max(o[0] for o in out), max(o[1] for o in out), TURN_SPEED)


def mirrored(moves: list[Move]) -> list[Move]:
    """The same moves turning the other way."""
    return [Move(m.length, -m.curvature, m.reverse, -m.sharpness) for m in moves]


class Shapes:
    """Each U-turn width's shape, chosen on the inverted chain and kept (one check a width): the
    followable one (within the limits ``turning`` chose R and sigma by) of least reach, of

    - two CC quarter turns at R with the straight between (where D >= 2 T), and
    - the CC half turn at R' >= R widened to D (clothoid.wider_radius);

    two quarters with a short straight between ask more than either quarter (the tractor, some
    15 m ahead of the working point, is in the second while the carts still come out of the
    first), so where they are not followable the widened half turn is taken; where neither is,
    the one asking the least steering (the plan says so)."""

    def __init__(self, train, turn: Turning):
        self.train, self.turn = train, turn
        self.P, self.lead = pack(train), lead_length(train)
        self.limit = min(turn.guard - STEERING_ROOM, STEERING_SHARE * train.actuator.max_angle)
        self.kept: dict = {}

    def check(self, moves) -> tuple[Demand, float, float]:
        """(demand, train reach, working point reach) of a left turn's ``moves`` between straights."""
        found = demand(self.train, check_path(self.turn.curves, self.lead, moves), P=self.P)
        outline, point = reach_of(self.train, found)
        return found, outline, point

    def u(self, offset: float) -> tuple[list[Move], float, bool]:
        """(moves, train reach, followable) of the U-turn ``offset`` across (>= min_u)."""
        width = round(abs(offset), 6)
        if width not in self.kept:
            curves = self.turn.curves
            options = []
            if width >= 2.0 * quarter(curves):
                options.append(u_moves(width, curves))
            options.append(cc_turn(math.pi, Curves(wider_radius(width, curves), curves.sharpness)))
            rated = []
            for moves in options:
                found, outline, _ = self.check(moves)
                ok = followable(found, self.limit, self.train.actuator.max_rate, SLACK)
                rated.append((not ok, outline if ok else found.steering, moves, outline, ok))
            _, _, moves, outline, ok = min(rated, key=lambda r: r[:2])
            self.kept[width] = (moves, outline, ok)
        moves, outline, ok = self.kept[width]
        return (moves if offset > 0 else mirrored(moves)), outline, ok

    def bulb_reach(self, offset: float) -> float:
        """m: the train's reach in a bulb ``|offset|`` across (its poses on the inverted chain)."""
        width = round(abs(offset), 6)
        key = ("bulb", width)
        if key not in self.kept:
            self.kept[key] = self.check(bulb_moves(width, self.turn.curves))[1]
        return self.kept[key]
