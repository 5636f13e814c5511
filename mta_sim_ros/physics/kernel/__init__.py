"""The train's kernel: the physics the simulator runs, written once, compiled by numba (or run as
plain Python: ``jit.py``). One compile unit with ``integrate/rk.py`` (the stepper), ``run/whole.py``
(a whole run in one call) and ``run/offsets.py`` (path distances).

    base.py      the layout of the arrays (packed constants, state, records), law and branch codes
    packing.py   the train's constants packed (plain Python)
    laws.py      steering actuator, resistances, traction limits, switch layout
    relief.py    a height grid's surface and each cart's grade resistance on it
    motion.py    rhs (chain walk + algorithm 2 + force laws), margin, outputs, drawbar pulls, switches
    entries.py   what Python calls, compiled and cached
    inverse.py   the kinematic chain inverted: the pose and steering that keep a cart's point on a path
    walk.py      the chain walk's arithmetic on numbers, its math bound: motion.rhs and batched.py run it
    batched.py   the right-hand side of a batch of schemes, one per SIMD lane (issue 24, docs/lanes.md)

The names below are this package's public face; the tests and the Python model levels use them.
"""
from .base import *  # noqa: F401,F403
from .entries import *  # noqa: F401,F403
from .laws import *  # noqa: F401,F403
from .motion import *  # noqa: F401,F403
from .relief import *  # noqa: F401,F403
from .packing import column, max_rate_of, pack, shape_of, stack  # noqa: F401
