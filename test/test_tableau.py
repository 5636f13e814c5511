"""Methods as data (integrate/tableau.py): each fixed-step method is its Butcher tableau, and what
the code derives from a table holds against closed forms and against the steps themselves.

- The order from the order conditions is each method's textbook order, and the error of the one
  stepping routine falls with that slope on a linear system with a closed-form solution.
- The stability polynomial is the Taylor polynomial of exp(z) of degree s for these s = p
  methods (exact, in rationals), and the real-axis limit is its closed-form root (Euler and Heun 2;
  Kutta's third order and RK4 the real roots of the cubics of R(-x) = 1, by Cardano's formula).
- The stepping routine does the textbook arithmetic of euler, heun and rk4 to the last bit.
- A table made here, not shipped, is stepped, ordered and bounded the same way: adding a method is
  adding a table.
"""
from __future__ import annotations

import math
from fractions import Fraction as F

import numpy as np
import pytest

from mta_sim_ros.integrate.stability import REAL_AXIS_LIMIT, stability_function
from mta_sim_ros.integrate.steppers import METHODS, FixedStep
from mta_sim_ros.integrate.tableau import TABLEAUX, Tableau
from mta_sim_ros.physics.spec import INTEGRATOR_METHODS

TEXTBOOK_ORDER = {"euler": 1, "heun": 2, "ralston": 2, "kutta3": 3, "rk4": 4, "rk38": 4}

# y' = A y: a damped rotation, y(t) = expm(A t) y0 in closed form
ALPHA, OMEGA = 0.3, 2.0
A = np.array([[-ALPHA, OMEGA], [-OMEGA, -ALPHA]])


def exact(t, y0):
    c, s = math.cos(OMEGA * t), math.sin(OMEGA * t)
    return math.exp(-ALPHA * t) * np.array([[c, s], [-s, c]]) @ y0


def error(method, h, T=2.0):
    y0 = np.array([1.0, 0.5])
    y = FixedStep(method, h).advance(lambda t, y: A @ y, 0.0, y0, T)
    return float(np.max(np.abs(y - exact(T, y0))))


def test_every_method_of_the_spec_has_a_stepper():
    assert set(METHODS) == set(INTEGRATOR_METHODS)
    assert set(TEXTBOOK_ORDER) == set(TABLEAUX)


@pytest.mark.parametrize("method", list(TABLEAUX))
def test_order_conditions_give_the_textbook_order(method):
    assert TABLEAUX[method].order == TEXTBOOK_ORDER[method]


@pytest.mark.parametrize("method", list(TABLEAUX))
def test_the_error_falls_with_the_order(method):
    slope = math.log2(error(method, 0.02) / error(method, 0.01))
    assert abs(slope - TEXTBOOK_ORDER[method]) < 0.15, slope


@pytest.mark.parametrize("method", list(TABLEAUX))
def test_stability_polynomial_is_the_taylor_polynomial_of_exp(method):
    """For s stages of order s, R(z) = sum_{k <= s} z^k / k! (exactly)."""
    tab = TABLEAUX[method]
    assert tab.stages == tab.order
    assert tab.stability_polynomial == tuple(F(1, math.factorial(k)) for k in range(tab.stages + 1))


def cardano(a, b, c):
    """The real root of x^3 + a x^2 + b x + c = 0 with one real root (closed form)."""
    p = b - a * a / 3.0
    q = 2.0 * a ** 3 / 27.0 - a * b / 3.0 + c
    disc = math.sqrt(q * q / 4.0 + p ** 3 / 27.0)
    return math.copysign(abs(-q / 2.0 + disc) ** (1 / 3), -q / 2.0 + disc) + \
        math.copysign(abs(-q / 2.0 - disc) ** (1 / 3), -q / 2.0 - disc) - a / 3.0


def test_real_axis_limits_are_the_closed_form_roots():
    # Euler |1 - x| = 1 at 2; Heun 1 - x + x^2/2 = 1 at 2 (it never reaches -1)
    assert REAL_AXIS_LIMIT["euler"] == pytest.approx(2.0, rel=1e-12)
    assert REAL_AXIS_LIMIT["heun"] == pytest.approx(2.0, rel=1e-12)
    assert REAL_AXIS_LIMIT["ralston"] == pytest.approx(2.0, rel=1e-12)  # the same R(z) as Heun
    # order 3: 1 - x + x^2/2 - x^3/6 = -1  <=>  x^3 - 3 x^2 + 6 x - 12 = 0
    assert REAL_AXIS_LIMIT["kutta3"] == pytest.approx(cardano(-3.0, 6.0, -12.0), rel=1e-12)
    # order 4: 1 - x + x^2/2 - x^3/6 + x^4/24 = 1  <=>  x (x^3 - 4 x^2 + 12 x - 24) = 0
    assert REAL_AXIS_LIMIT["rk4"] == pytest.approx(cardano(-4.0, 12.0, -24.0), rel=1e-12)
    assert REAL_AXIS_LIMIT["rk38"] == REAL_AXIS_LIMIT["rk4"]


@pytest.mark.parametrize("method", list(TABLEAUX))
def test_a_decaying_mode_decays_below_the_limit_and_grows_past_it(method):
    x = REAL_AXIS_LIMIT[method]
    assert abs(abs(stability_function(method, -x)) - 1.0) < 1e-9
    assert all(abs(stability_function(method, -u)) < 1.0 for u in np.linspace(1e-3, 0.999 * x, 200))
    assert abs(stability_function(method, -1.01 * x)) > 1.0
    # and the step itself does what R says: one step of y' = -y with h = u multiplies y by R(-u)
    for u in (0.5 * x, 0.99 * x, 1.01 * x):
        y = FixedStep(method, u).advance(lambda t, y: -y, 0.0, np.array([1.0]), u)
        assert y[0] == pytest.approx(stability_function(method, -u).real, rel=1e-12)


def textbook(method, f, y, h):
    """The methods as printed, in numpy."""
    k1 = f(y)
    if method == "euler":
        return y + h * k1
    if method == "heun":
        k2 = f(y + h * k1)
        return y + 0.5 * h * (k1 + k2)
    k2 = f(y + 0.5 * h * k1)
    k3 = f(y + 0.5 * h * k2)
    k4 = f(y + h * k3)
    return y + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


@pytest.mark.parametrize("method", ["euler", "heun", "rk4"])
def test_the_stepping_routine_is_the_textbook_arithmetic_bit_for_bit(method):
    rng = np.random.default_rng(3)
    M = rng.normal(size=(6, 6))

    def f(y):
        return np.sin(M @ y) - 0.1 * y ** 3

    for _ in range(20):
        y0, h = rng.normal(size=6), rng.uniform(1e-3, 0.1)
        got = FixedStep(method, h).advance(lambda t, y: f(y), 0.0, y0, h)
        np.testing.assert_array_equal(got, textbook(method, f, y0, h))


def test_a_new_table_is_a_new_method():
    """The explicit midpoint method, written here as data only."""
    midpoint = Tableau("midpoint", ((), (F(1, 2),)), (F(0), F(1)))
    assert midpoint.order == 2 and midpoint.c == (F(0), F(1, 2))
    assert midpoint.real_axis_limit == pytest.approx(2.0, rel=1e-12)
    y0 = np.array([1.0, 0.5])
    e = [float(np.max(np.abs(FixedStep(midpoint, h).advance(lambda t, y: A @ y, 0.0, y0, 2.0) - exact(2.0, y0))))
         for h in (0.01, 0.005)]
    assert math.log2(e[0] / e[1]) == pytest.approx(2.0, abs=0.15)


def test_a_malformed_table_is_refused():
    with pytest.raises(ValueError, match="rows of 0, 1"):
        Tableau("bad", ((), (F(1), F(1))), (F(1, 2), F(1, 2)))
