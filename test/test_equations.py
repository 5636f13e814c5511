"""The printed equations (equations.py, mta equations) evaluate to the numeric model: V' parsed
back from the printed text (1 and 2 carts) and the built expression (up to 5 carts), with the
train's numbers and the kernel's forces, against the kernel's y' on random states, to 1e-12."""
from __future__ import annotations

import math
import re

import numpy as np
import pytest
import sympy as sp

from mta_sim_ros import cli
from mta_sim_ros.config import resolve_config_path
from mta_sim_ros.physics import kernel, loader
from mta_sim_ros.symbolic import equations

TRAINS = ["single_tractor", "offset_hitch", "light_tractor_heavy_cart", "default",
          pytest.param("long_train", marks=pytest.mark.slow)]


def load(name):
    return loader.load_train(resolve_config_path(f"trains/{name}.yaml"))


def random_state(rng, train):
    n = train.n
    heading = [rng.uniform(-math.pi, math.pi)]
    for _ in range(n - 1):
        heading.append(heading[-1] - rng.uniform(-0.8, 0.8))
    psi = rng.uniform(-0.6, 0.6)
    V = rng.choice([-1.0, 1.0]) * rng.uniform(0.2, 6.0)
    return np.array([rng.uniform(-9, 9), rng.uniform(-9, 9), *heading, psi, V, rng.uniform(-3e4, 3e4)]), \
        rng.uniform(-0.7, 0.7)


def kernel_point(train, y, command):
    """(values of the state symbols and forces, the kernel's V') at a state: F_A1 and F_Bk as the
    kernel's outputs give them, psi_1' its right-hand side's."""
    P = kernel.pack(train)
    dy = kernel.rhs_of(P, y, command, 3.0, kernel.max_rate_of(P))
    cart, sc = kernel.outputs_of(P, y, command, 3.0, kernel.max_rate_of(P))
    n = train.n
    values = {f"theta_{k + 1}": y[2 + k] for k in range(n)}
    values.update({"psi_1": y[n + 2], "V": y[n + 3], "dpsi_1": dy[n + 2], "F_A1": sc[kernel.TRACTION]})
    values.update({f"F_B{k + 1}": cart[k, kernel.RES] for k in range(n)})
    return values, dy[n + 3]


_COMPILED: dict = {}


def evaluate(expr, eq, values):
    """expr at the train's numbers and ``values`` (lambdify, floats)."""
    names = sorted(values)
    key = (eq.train.name, id(expr), tuple(names))  # the same symbols, another train: other numbers
    if key not in _COMPILED:
        _COMPILED[key] = (expr, sp.lambdify([eq.symbols[n] for n in names], expr.subs(eq.values), "math"))
    return float(_COMPILED[key][1](*(values[n] for n in names)))


@pytest.mark.parametrize("name", TRAINS)
def test_the_built_acceleration_is_the_kernels(name):
    train = load(name)
    eq = equations.build(train)
    rng = np.random.default_rng(len(name))
    for _ in range(6):
        y, command = random_state(rng, train)
        values, expected = kernel_point(train, y, command)
        assert evaluate(eq.acceleration, eq, values) == pytest.approx(expected, rel=1e-12, abs=1e-12)


@pytest.mark.parametrize("name", ["single_tractor", "offset_hitch", "light_tractor_heavy_cart", "default"])
def test_the_printed_acceleration_parsed_back_is_the_kernels(name, capsys):
    """The V' line that ``mta equations`` prints, read back by sympy from the text alone (the
    3-cart unit with ``--expand-up-to 3``)."""
    train = load(name)
    assert cli.main(["equations", f"trains/{name}.yaml", "--expand-up-to", "3"]) == 0
    text = capsys.readouterr().out
    [line] = [l for l in text.splitlines() if l.startswith("V' = ")]
    eq = equations.build(train)
    printed = sp.sympify(line[len("V' = "):], locals=eq.symbols)
    rng = np.random.default_rng(7)
    for _ in range(6):
        y, command = random_state(rng, train)
        values, expected = kernel_point(train, y, command)
        assert evaluate(printed, eq, values) == pytest.approx(expected, rel=1e-12, abs=1e-12)
    # and the structural matrices' entries are the kernel's chain
    P = kernel.pack(train)
    y, command = random_state(rng, train)
    values, _ = kernel_point(train, y, command)
    cart, _ = kernel.outputs_of(P, y, command, 3.0, kernel.max_rate_of(P))
    for k in range(train.n):
        for key, column in (("kapC", kernel.KAPC), ("kapT", kernel.KAPT), ("kapB", kernel.KAPB)):
            [entry] = [l for l in text.splitlines() if l.startswith(f"{key}_{k + 1} = ")]
            value = evaluate(sp.sympify(entry.split(" = ", 1)[1], locals=eq.symbols), eq, values)
            assert value == pytest.approx(cart[k, column], rel=1e-12, abs=1e-14)


@pytest.mark.parametrize("name", ["single_tractor", "offset_hitch", "default"])
def test_on_a_tilted_plane_the_printed_acceleration_has_the_kernels_grade_terms(name, tmp_path, capsys):
    """A scene on a plane tilted both ways: its train's V' with the grade resistances F_gk, built
    and printed (``mta equations SCENE``, read back from the text), against the kernel's y' on the
    plane at random states; the level's equations have no F_gk, the plane's differ from them."""
    import dataclasses

    from mta_sim_ros.physics.terrain import Plane

    scene = tmp_path / "tilted.yaml"
    scene.write_text(f"train: {resolve_config_path(f'trains/{name}.yaml')}\nduration: 5\n"
                     "steering: {maneuver: straight}\nterrain: {grade_percent: -7, cross_slope_percent: 15}\n",
                     encoding="utf-8")
    train = dataclasses.replace(load(name), terrain=Plane(-0.07, 0.15))
    assert cli.main(["equations", str(scene), "--expand-up-to", "3"]) == 0
    text = capsys.readouterr().out
    [line] = [l for l in text.splitlines() if l.startswith("V' = ")]
    eq = equations.build(train)
    assert len(eq.grade) == train.n and "F_g1 = " in text and not equations.build(load(name)).grade
    printed = sp.sympify(line[len("V' = "):], locals=eq.symbols)
    rng = np.random.default_rng(11)
    for _ in range(6):
        y, command = random_state(rng, train)
        values, expected = kernel_point(train, y, command)
        level = kernel_point(load(name), y, command)[1]
        assert abs(expected - level) > 1e-3
        assert evaluate(printed, eq, values) == pytest.approx(expected, rel=1e-12, abs=1e-12)
        assert evaluate(eq.acceleration, eq, values) == pytest.approx(expected, rel=1e-12, abs=1e-12)


def test_the_recursion_printed_is_the_chain():
    """The printed step, cart k from cart k-1, composed twice for the default unit gives the kernel's
    th'_3 (the recursion is the chain's, on symbols)."""
    train = load("default")
    eq = equations.build(train)
    rec = eq.recursion
    rng = np.random.default_rng(11)
    y, command = random_state(rng, train)
    P = kernel.pack(train)
    cart, _ = kernel.outputs_of(P, y, command, 3.0, kernel.max_rate_of(P))
    psi, V = y[5], y[6]
    sym = {str(s): s for e in rec.values() for s in e.free_symbols}
    for k in range(1, train.n):
        prev, cur = train.carts[k - 1], train.carts[k]
        at = {sym["psi_{k-1}"]: psi, sym["V_{k-1}"]: V, sym["theta_{k-1}"]: y[1 + k], sym["theta_k"]: y[2 + k],
              sym["l_{k-1}"]: prev.length, sym["a_{k-1}"]: prev.hitch_offset}
        psi, V = float(rec["psi_k"].subs(at)), float(rec["V_k"].subs(at))
        own = {sym["psi_k"]: psi, sym["V_k"]: V, sym["l_k"]: cur.length, sym["c_k"]: cur.com_offset}
        assert float(rec["theta'_k"].subs(own)) == pytest.approx(cart[k, kernel.VT], rel=1e-12)
        assert float(rec["s'_Ck"].subs(own)) == pytest.approx(cart[k, kernel.VC], rel=1e-12)


def test_latex_and_numbers(capsys):
    assert cli.main(["equations", "trains/offset_hitch.yaml", "--format", "latex", "--numbers"]) == 0
    text = capsys.readouterr().out
    assert "\\begin{align*}" in text and "l_{1}" not in text.split("## Structural matrices")[1]
    assert re.search(r"V' &= ", text)


def test_a_long_train_prints_its_recursion_and_refuses_nothing(capsys):
    """The 20-cart train: the recursion (the same step as the 3-cart unit's: it is one cart's) and
    the element lists, the expanded forms left out with a line saying how to get them."""
    assert cli.main(["equations", "trains/long_train_20.yaml"]) == 0
    text = capsys.readouterr().out
    assert "- cart 20 (trolley_19)" in text and "(F_B20, s'_B20)" in text
    assert "expanded for n <= 2 only: --expand-up-to" in text and "\nV' = " not in text
    assert cli.main(["equations", "trains/default.yaml"]) == 0
    short = capsys.readouterr().out
    recursion = lambda t: t.split("## The recursion")[1].split("## Structural")[0]  # noqa: E731
    assert recursion(text) == recursion(short)


@pytest.mark.parametrize("value", ["6", "-1", "x", "2.5", "", "99999999999999999999"])
def test_an_expansion_too_large_is_refused_in_one_line(value, capsys):
    assert cli.main(["equations", "trains/default.yaml", "--expand-up-to", value]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--expand-up-to" in err and "0 to 5" in err, err
