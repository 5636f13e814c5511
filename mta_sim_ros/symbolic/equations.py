"""The equations of motion of a hitching scheme, printed as the article states them (``mta equations``).

Built symbolically (sympy) from the train file by the model's own code: the kinematic chain
(``chain.chain``) and algorithm 2's sums (``dynamics.mass_terms``, ``resistance_force``,
``cauchy_acceleration``) run on symbols, so what is printed is what the simulator computes:

* the element lists: inertial elements (m_k, s'_Ck) and (J_k, th'_k), force elements (F_A1, s'_A1)
  and (F_Bk, s'_Bk), with the train's carts and forces;
* the per-cart recursion: psi_k, V_k, th'_k, s'_Bk, s'_Ck of cart k from cart k-1's (one step of the
  chain on symbols), psi_1 the steering angle, V_1 = V;
* the structural matrices W_J = d(s'_Ck, th'_k)/dV and W_P = d(s'_A1, s'_Bk)/dV, the reduced mass
  M(q, psi_1) = W_J^T diag(m, J) W_J, the generalized force Q, dM/dt;
* on a scene's tilted plane (a scene file, or a train whose ``terrain`` is set), gravity's
  component in the plane (g_x, g_y) as one more force element per cart: the grade resistance
  F_gk = -m_k g_p . v_Ck / V (``kernel.grade_resistance``), in Q as the resistances are;
* the Cauchy form q' = G(q, psi_1) V, psi_1' = actuator, V' = (Q - 1/2 M' V) / M;
* for n <= ``expand_up_to`` (``render``'s, default 2), the structural matrices, M, Q, dM/dt and V'
  expanded in the pose, the steering angle and its rate, V and the forces (they swell about 3x per
  cart: longer trains keep the recursion, which prints for any n).

Symbols: theta_k headings, psi_1 the steering angle and dpsi_1 = psi_1' its rate (the actuator's), V the speed
of A_1, l_k, a_k, c_k the cart's length, hitch offset and centre-of-mass offset (lam_k = a_k / l_k,
mu_k = c_k / l_k), m_k, J_k, F_A1 the traction, F_Bk the resistance at B_k. ``numbers=True``
substitutes the train file's values for the constants (not for the state or the forces).
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass
class Equations:
    train: object
    symbols: dict  # name -> sympy Symbol
    values: dict  # Symbol -> the train's number
    rates: list  # th'_k
    grade: list  # F_gk, each cart's grade resistance referred to V (empty on the level)
    kapB: list
    kapC: list
    kapT: list
    psi: list
    kap: list
    mass: object  # M
    mass_rate: object  # M'
    force: object  # Q
    acceleration: object  # V'
    recursion: dict  # one step: name -> expression in cart k-1's symbols


def build(train) -> Equations:
    """The symbolic model of ``train`` (module docstring)."""
    import sympy as sp

    from ..physics.chain import ChainGeometry, chain
    from ..physics.dynamics import cauchy_acceleration, mass_terms, resistance_force

    n = train.n
    idx = range(1, n + 1)
    th = sp.symbols(" ".join(f"theta_{k}" for k in idx))
    th = (th,) if n == 1 else th
    psi1, rate, V = sp.symbols("psi_1 dpsi_1 V")
    l = [sp.Symbol(f"l_{k}", positive=True) for k in idx]
    a = [sp.Symbol(f"a_{k}") for k in idx]
    c = [sp.Symbol(f"c_{k}") for k in idx]
    m = [sp.Symbol(f"m_{k}", positive=True) for k in idx]
    J = [sp.Symbol(f"J_{k}", positive=True) for k in idx]
    F = sp.Symbol("F_A1")
    FB = [sp.Symbol(f"F_B{k}") for k in idx]
    geom = ChainGeometry(tuple(l), tuple(ak / lk for ak, lk in zip(a, l)), tuple(ck / lk for ck, lk in zip(c, l)))
    ch = chain(geom, list(th), psi1, V, rate, fn=sp)
    mass, velocity_term = mass_terms(m, J, ch, V)
    gx, gy = sp.symbols("g_x g_y")
    grade = [] if train.terrain is None else [  # kernel.grade_resistance on symbols
        -mk * (gx * (kb * sp.cos(t) - ck * kt * sp.sin(t)) + gy * (kb * sp.sin(t) + ck * kt * sp.cos(t)))
        for mk, ck, t, kb, kt in zip(m, c, th, ch.kapB, ch.kapT)]
    slopes = ()
    if train.relief is not None:  # kernel.relief_grade on symbols: grad z at C_k = (G_xk, G_yk), a function of the pose
        g = sp.Symbol("g", positive=True)
        slopes = (g, *(sp.Symbol(f"G_x{k}") for k in idx), *(sp.Symbol(f"G_y{k}") for k in idx))
        grade = [mk * g * (Gx * (kb * sp.cos(t) - ck * kt * sp.sin(t)) + Gy * (kb * sp.sin(t) + ck * kt * sp.cos(t)))
                 for mk, ck, t, kb, kt, Gx, Gy in zip(m, c, th, ch.kapB, ch.kapT, slopes[1:n + 1], slopes[n + 1:])]
    resisting = resistance_force(FB, ch.kapB) + sum(grade)
    force = F - resisting
    accel = cauchy_acceleration(F, resisting, velocity_term, mass)
    # the recursion, from the same chain on symbols: cart k's own speeds from its psi_k and V_k, and
    # one step from cart k-1 to cart k (psi_k, V_k from cart k-1's)
    pk, Vk, lk, ck, tk = sp.symbols("psi_k V_k l_k c_k theta_k")
    own = chain(ChainGeometry((lk,), (0,), (ck / lk,)), [tk], pk, Vk, 0, fn=sp)
    pp, Vp, lp, ap, tp = sp.symbols("psi_{k-1} V_{k-1} l_{k-1} a_{k-1} theta_{k-1}")
    step = chain(ChainGeometry((lp, lk), (ap / lp, 0), (0, 0)), [tp, tk], pp, Vp, 0, fn=sp)
    recursion = {
        "psi_k": step.psi[1],
        "V_k": step.kap[1] * Vp,
        "theta'_k": own.kapT[0] * Vk,
        "s'_Bk": own.kapB[0] * Vk,
        "s'_Ck": own.kapC[0] * Vk,
    }
    symbols = {str(s): s for s in (*th, psi1, rate, V, *l, *a, *c, *m, *J, F, *FB, *((gx, gy) if train.terrain is not None else ()), *slopes)}
    values = {slopes[0]: train.gravity} if slopes else {}
    if train.terrain is not None:
        from ..physics.terrain import PlaneFrame

        values[gx], values[gy], _ = PlaneFrame.of(train.terrain).gravity(train.gravity)
    for k, cart in enumerate(train.carts):
        values.update({l[k]: cart.length, a[k]: cart.hitch_offset, c[k]: cart.com_offset, m[k]: cart.mass,
                       J[k]: cart.yaw_inertia})
    return Equations(train, symbols, values, [kt * V for kt in ch.kapT], grade, ch.kapB, ch.kapC, ch.kapT, ch.psi,
                     ch.kap, mass, 2 * velocity_term / V, force, accel, recursion)


def render(eq: Equations, fmt: str = "markdown", numbers: bool = False, expand_up_to: int = 2) -> str:
    """The equations as Markdown (sympy's plain text in code blocks) or LaTeX."""
    import sympy as sp

    def show(expr):
        expr = sp.sympify(expr)  # the chain's 1.0, 2.0, 0.5 as the numbers they are
        expr = expr.xreplace({f: sp.Rational(round(2 * float(f)), 2) for f in expr.atoms(sp.Float)
                              if 2 * float(f) == round(2 * float(f))})
        expr = expr.subs(eq.values) if numbers else expr
        return sp.latex(expr) if fmt == "latex" else sp.sstr(expr)

    def block(lines):
        if fmt == "latex":
            return ["\\begin{align*}", *(f"{lhs} &= {rhs} \\\\" for lhs, rhs in lines), "\\end{align*}", ""]
        return ["```", *(f"{lhs} = {rhs}" for lhs, rhs in lines), "```", ""]

    tr = eq.train
    n = tr.n
    out = [f"# Equations of motion of {tr.name} ({n} cart{'s' * (n > 1)})", ""]
    out += ["## Element lists", "", "Inertial elements (mass or inertia, the speed it moves with):", ""]
    out += [f"- cart {k} ({c.name}): (m_{k} = {c.mass:g} kg, s'_C{k}), (J_{k} = {c.yaw_inertia:g} kg m^2, "
            f"theta'_{k}); l_{k} = {c.length:g} m, a_{k} = {c.hitch_offset:g} m, c_{k} = {c.com_offset:g} m"
            for k, c in enumerate(tr.carts, 1)]
    forces = [f"- (F_A1, s'_A1 = V): traction at A_1, law {tr.traction.law}"]
    for k, c in enumerate(tr.carts, 1):
        parts = [f"rolling f = {r.coefficient:g}" for r in tr.rolling if r.cart == c.name]
        parts += [f"draft {d.soil_factor:g} x ({d.A:g} + {d.B:g} S + {d.C:g} S^2) x {d.width:g} x {d.depth:g}"
                  for d in tr.draft if d.cart == c.name]
        forces.append(f"- (F_B{k}, s'_B{k}): at B_{k}, against its motion" + (f": {', '.join(parts)}" if parts else ""))
    if eq.grade and tr.terrain is not None:
        gx, gy = eq.values[eq.symbols["g_x"]], eq.values[eq.symbols["g_y"]]
        forces.append(f"- (F_gk, V) for each cart: gravity's component in the plane g_p = (g_x, g_y) = ({gx:.6g}, "
                      f"{gy:.6g}) m/s^2 at C_k (terrain: grade {tr.terrain.grade:g}, cross slope "
                      f"{tr.terrain.cross_slope:g}), F_gk = -m_k g_p . v_Ck / V, v_Ck / V = kapB_k e_k + c_k kapT_k n_k")
    if tr.relief is not None:
        forces.append(f"- (F_gk, V) for each cart on the height grid {tr.relief!r}: the potential m_k g z(C_k), "
                      "F_gk = m_k g (G_xk, G_yk) . v_Ck / V, (G_xk, G_yk) = grad z at C_k (the grid's bicubic spline, "
                      "a function of the pose), v_Ck / V = kapB_k e_k + c_k kapT_k n_k; x, y horizontal")
    out += ["", "Force elements (force, the speed of its point):", "", *forces, ""]
    out += ["## The recursion (cart k from cart k-1; psi_1 the steering angle, V_1 = V)", ""]
    out += block([(name, show(expr)) for name, expr in eq.recursion.items()])
    out += ["## Structural matrices", "", "W_J = d(s'_C1, theta'_1, ..., s'_Cn, theta'_n)/dV, "
            "W_P = d(s'_A1, s'_B1, ..., s'_Bn)/dV:", ""]
    if n <= expand_up_to:  # the expanded forms double in size with each cart: only for short trains
        rows = []
        for k in range(n):
            rows += [(f"kapC_{k + 1}", show(eq.kapC[k])), (f"kapT_{k + 1}", show(eq.kapT[k]))]
        rows += [("kapA_1", "1")] + [(f"kapB_{k + 1}", show(eq.kapB[k])) for k in range(n)]
        out += block(rows)
    else:
        out += [f"(expanded for n <= {expand_up_to} only: --expand-up-to; the recursion gives them)", ""]
    out += ["## Reduced mass, generalized force, dM/dt", "",
            "M = sum_k m_k kapC_k^2 + J_k kapT_k^2 (= W_J^T diag(m, J) W_J), Q = F_A1 - sum_k F_Bk kapB_k, "
            "dM/dt = sum_k 2 (m_k kapC_k kapC_k' + J_k kapT_k kapT_k'), the rates along the motion with "
            "theta'_k = kapT_k V and dpsi_1 = psi_1' the actuator's rate.", ""]
    if eq.grade:
        out += ["On the plane Q = F_A1 - sum_k F_Bk kapB_k - sum_k F_gk, F_gk > 0 while cart k climbs.", ""]
    if n <= expand_up_to:
        grades = [(f"F_g{k + 1}", show(f)) for k, f in enumerate(eq.grade)]
        out += block([*grades, ("M", show(eq.mass)), ("Q", show(eq.force)), ("dM/dt", show(eq.mass_rate))])
    out += ["## Cauchy form", "",
            "x' = V cos(theta_1 + psi_1), y' = V sin(theta_1 + psi_1), theta_k' = kapT_k V, psi_1' = the actuator "
            f"(psi_1' = clip((clip(u, +-{tr.actuator.max_angle:.4g}) - psi_1) / {tr.actuator.time_constant:g}, "
            f"+-{tr.actuator.max_rate:g})), V' = (Q - 1/2 M' V) / M:", ""]
    if n <= expand_up_to:
        out += block([("V'", show(eq.acceleration))])
    else:
        out += [f"(V' expanded for n <= {expand_up_to} only: it swells about 3x per cart)", ""]
    return "\n".join(out)
