"""The benchmarks: measurements, not tests, of a source checkout (not installed with the package,
as scipy keeps its ``benchmarks/`` beside the package). Run one from the repository root with
``python -m benchmarks NAME [options]`` (``make bench BENCH="NAME options"``). Each prints its figures and writes them to Markdown
(``tick-parts`` only prints). One module a benchmark:

realtime        the node at real-time factor 1, steered over DDS by a player process (realtime.py,
                player.py; ``--stages``: the node's tick profile, stages.py)
method          the integrators on one scene at the node's tick: error against cost, the default to choose
work-precision  error against CPU time of every integrator on six scenes, node and free mode
stability       where every method's steps stop being accurate, and where they blow up
scaling         the node's tick against carts and publish rate, long runs, memory (scaling.py,
                scaling_report.py)
fidelity        each fidelity level's error against slip and its cost
tick-parts      the tick's parts in two forms, side by side
kinks           every method across the right-hand side's kinks, split and not
sigkill         the simulated time a SIGKILL of the node loses from its bag, per rate and real-time factor
flood           the node under a flood of steering commands: deadline misses, tick percentiles, lag,
                memory (flood.py, flooder.py)
sweep           a sweep's run against run_scene, fidelity auto's set-up, 1 and 2 workers, runs against time
reverse         the reversing controller: speeds, train lengths and offsets where it holds and where it folds
field           mta field run on a whole field: wall time on one core and where it goes

Shared: common.py (report header and writing, scene paths, child processes' environment, timing
side by side), runs.py (node-mode runs of a scene with held inputs, hitch points, errors against a
reference). Every process started here that talks DDS gets ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
and a domain of its own.
"""
from __future__ import annotations

#: the benchmarks' modules; each has HELP, add_arguments(parser) and main(args); the command is
#: the module's name with '-' for '_'
MODULES = ("realtime", "method", "work_precision", "stability", "scaling", "fidelity", "tick_parts", "kinks",
           "sigkill", "flood", "sweep", "reverse", "field")
