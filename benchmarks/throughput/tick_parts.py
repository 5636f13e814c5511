"""``python -m benchmarks tick-parts``: the parts of the node's tick that exist in two forms, timed side by side
in one process, offline, calls back to back, on a state of the scene after 3 s of its own inputs:
the five output messages built as plain dicts (``topics.output_messages``) and encoded by the
generic serializer (``bag.cdr.encode``) against ``messages.OutputEncoder.encode`` (CDR templates;
the same bytes); the MarkerArray likewise (``messages.train_markers`` encoded against
``TrainMarkers.encode``); the level's ``outputs`` with the kernel as plain Python against
``Simulation.outputs`` on the compiled path (the tick's form second). The variants alternate within
each round, so both see the same machine; printed: the median over rounds of the mean time per
call, and the ratio. No file is written.
"""
from __future__ import annotations

import statistics

from mta_sim_ros.validate import COUNT, number_arg

from ..common import DEFAULT_SCENE, resolve_scene, side_by_side

HELP = ("the node tick's parts in two forms (generic against template, Python against compiled), "
        "side by side offline")


def add_arguments(p) -> None:
    p.add_argument("--scene", default=DEFAULT_SCENE, help=f"scene YAML (default {DEFAULT_SCENE})")
    p.add_argument("--rounds", type=number_arg(COUNT, int), default=30, help="rounds; each times every variant once (default 30)")
    p.add_argument("--calls", type=number_arg(COUNT, int), default=100, help="calls per variant per round (default 100)")


def main(args) -> int:
    from mta_sim_ros.bag.cdr import encode
    from mta_sim_ros.messages import MARKERS_TYPE, OutputEncoder, TrainMarkers, train_markers
    from mta_sim_ros.messages.topics import TOPICS, output_messages
    from mta_sim_ros.physics.loader import load_scene
    from mta_sim_ros.run.simulation import Simulation

    scene = load_scene(resolve_scene(args.scene))
    sim = Simulation(scene, fidelity="dynamic")
    while sim.t < 3.0:
        sim.advance(*sim.scheduled_inputs(sim.t))
    out = sim.outputs()
    names = [c.name for c in scene.train.carts]
    encoder, markers = OutputEncoder(names), TrainMarkers(scene.train)
    pairs = {
        "five output messages": (lambda: [encode(TOPICS[t], m) for t, m in output_messages(out, names).items()],
                                 lambda: encoder.encode(out)),
        "markers (MarkerArray)": (lambda: encode(MARKERS_TYPE, train_markers(out, scene.train)),
                                  lambda: markers.encode(out)),
        "outputs": (lambda: sim.model.outputs(sim.t, sim.y, sim.command, sim.v_set, compiled=False), sim.outputs),
    }
    print(f"benchmarks tick-parts: scene '{scene.name}', {len(names)} carts, outputs path: {sim.compiled_note}; "
          f"{args.rounds} rounds x {args.calls} calls per variant")
    print(f"  {'part':<24} {'general, us':>12} {'tick, us':>9} {'general / tick':>15}")
    for label, (general, tick) in pairs.items():
        times = side_by_side({"general": general, "tick": tick}, args.rounds, args.calls)
        old, new = statistics.median(times["general"]), statistics.median(times["tick"])
        print(f"  {label:<24} {old * 1e6:12.1f} {new * 1e6:9.1f} {old / new:15.1f}")
    return 0
