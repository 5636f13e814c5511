"""The plain-C floor of ``python -m benchmarks sweep-lanes`` (benchmarks/throughput/run_floor.c) is the
kernel's arithmetic: built one scheme at a time, its rk4 step is rk_lanes' step bit for bit, and its
runs end bit for bit where the kernel's steps end them; built eight schemes a vector, it calls glibc's
vector math and stays within round-off of the kernel. A floor that drifted from the kernel would
measure something else."""
from __future__ import annotations

import dataclasses
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from benchmarks.throughput import sweep_floor
from benchmarks.common import random_train
from benchmarks.throughput.lanes_rhs import batch
from mta_sim_ros.config import resolve_config_path
from mta_sim_ros.physics.loader import load_scene

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None and not os.environ.get("CI"),
                                reason="no C compiler: the benchmark leaves the floor out (CI has one: never skipped there)")


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    libs, how = sweep_floor.build(Path(tmp_path_factory.mktemp("floor")))
    assert libs, how
    return libs, how


@pytest.mark.parametrize("n", [1, 2, 3, 5])
def test_one_step_is_the_kernels(built, n):
    """Random trains, states and inputs; a third of the lanes on the actuator's rate limit."""
    P, y, commands, v_sets, _ = batch(n, 16, seed=7 + n)["lanes"]
    seen = sweep_floor.check(built[0], P, y, commands, v_sets, 0.02)
    assert seen["one_bit_identical"]
    assert seen["lanes_max_rel"] < 1e-13


def test_the_vector_build_calls_vector_math(built):
    assert "_ZGV" in built[1] and "atan2" in built[1] and "tanh" in built[1], built[1]


@pytest.mark.slow
def test_runs_end_where_the_kernels_steps_end(built):
    """The headland run's 3500 ticks of 8 random 3-cart trains: C alone to the bit, C across lanes
    within round-off of the kernel across lanes."""
    scene = load_scene(resolve_config_path("scenes/headland_turn.yaml"))
    rng = np.random.default_rng(11)
    scenes = [dataclasses.replace(scene, train=random_train(3, rng)) for _ in range(8)]
    calls, checks = sweep_floor.variants(built[0], scenes, alone=8, widths=(8,))
    assert set(calls) == {"kernel steps alone", "C alone", "kernel steps lanes 8", "C lanes 8"}
    assert checks["C alone equals the kernel's steps to the bit"]
    assert checks["C lanes against the kernel's lanes, largest difference / row scale"] < 1e-9


def test_a_train_with_two_drafts_on_a_cart_is_refused():
    P, *_ = batch(3, 8)["lanes"]
    P = P.copy()
    from mta_sim_ros.physics.kernel import CART_SIZE, HEAD_SIZE, C

    P[HEAD_SIZE + CART_SIZE * 2 + C.draft_count] = 2.0
    with pytest.raises(ValueError, match="at most one draft"):
        sweep_floor.constants(P, 8)


def test_a_train_longer_than_the_c_arrays_is_refused():
    assert f"#define MAXN {sweep_floor.MAX_CARTS}\n" in sweep_floor.SOURCE.read_text()
    P, *_ = batch(sweep_floor.MAX_CARTS + 1, 8)["lanes"]
    with pytest.raises(ValueError, match=f"at most {sweep_floor.MAX_CARTS} carts"):
        sweep_floor.constants(P, 8)
