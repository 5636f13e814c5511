"""The benchmarks: measurements, not tests, of a source checkout (not installed with the package,
as scipy keeps its ``benchmarks/`` beside the package). Run one from the repository root with
``python -m benchmarks NAME [options]``. Each prints its figures and writes them to Markdown
(``tick-parts`` only prints). One module a benchmark, in four folders by what they measure:

accuracy/     error against cost
  method          the integrators on one scene at the node's tick: error against cost, the default to choose
  work-precision  error against CPU time of every integrator on six scenes, node and free mode
  stability       where every method's steps stop being accurate, and where they blow up
  kinks           every method across the right-hand side's kinks, split and not
  fidelity        each fidelity level's error against slip and its cost
  estimate        each run's stated position error against the true one; what asking for a tolerance costs
throughput/   how much is done in a second
  scaling         the node's tick against carts and publish rate, long runs, memory (scaling_report.py
                  writes its report)
  tick-parts      the tick's parts in two forms, side by side
  sweep           a sweep's run against run_scene, fidelity auto's set-up, 1 and 2 workers, runs against time
  field           mta field run on a whole field: wall time on one core and where it goes
  lanes           the lanes' math (physics/kernel/vmath.py) against libm, numpy and gcc's libmvec:
                  ns per value, accuracy, the instructions each loop compiled to; the shapes of a
                  loop over schemes that LLVM vectorises (lanes_shapes.py)
  sweep-lanes     a sweep's run across SIMD lanes (run/lanes_batch.py) against alone, by batch width
                  and carts: ms per run, runs/s/core, the metrics' largest difference, peak memory
node/         the running node over DDS
  realtime        the node at real-time factor 1, steered by a player process (player.py; ``--stages``: the
                  node's tick profile, stages.py)
  sigkill         the simulated time a SIGKILL of the node loses from its bag, per rate and real-time factor
  flood           the node under a flood of steering commands: deadline misses, tick percentiles, lag,
                  memory (flooder.py)
controllers/  the example controllers
  reversing       the reversing controller: speeds, train lengths and offsets where it holds and where it folds

Shared: common.py (report header and writing, scene paths, child processes' environment, timing
side by side), runs.py (node-mode runs of a scene with held inputs, hitch points, errors against a
reference), stages.py (the node's tick profile). Every process started here that talks DDS gets
ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST and a domain of its own.

``benchmarks`` is a namespace package (no __init__.py): the folder is not installed, and a tool that
looks for the one folder of the repository with an __init__.py finds the package, mta_sim_ros.
"""
from __future__ import annotations

#: the benchmarks: the command (the module's name with '-' for '_') -> its module in this package;
#: each has HELP, add_arguments(parser) and main(args)
MODULES = {
    "method": "accuracy.method", "work_precision": "accuracy.work_precision", "stability": "accuracy.stability",
    "kinks": "accuracy.kinks", "fidelity": "accuracy.fidelity", "estimate": "accuracy.estimate",
    "scaling": "throughput.scaling", "tick_parts": "throughput.tick_parts", "sweep": "throughput.sweep",
    "field": "throughput.field", "lanes": "throughput.lanes",
    "sweep_lanes": "throughput.sweep_lanes",
    "realtime": "node.realtime", "sigkill": "node.sigkill", "flood": "node.flood",
    "reversing": "controllers.reversing",
}
