"""The library versions the package runs on, their differences in one place. No physics.

Two Python stacks are tested (docs/dependencies.md): Ubuntu 24.04's, which a ROS 2
Jazzy install uses (numpy 1.26.4, scipy 1.11.4, matplotlib 3.6.3, numba 0.59.1:
constraints-noble.txt, ``make test-noble``), and current PyPI's (requirements.txt, ``make test``).
Where the newer libraries renamed or added what the package uses, the package calls the name
here, which is the newer library's own on the newer stack and its equivalent on the older one.
"""
from __future__ import annotations

import numpy as np

#: ``numpy.trapezoid`` (numpy >= 2.0); on numpy 1.x the same function under its old name, ``trapz``
#: (the same arithmetic: sum of diff(x) * (y[1:] + y[:-1]) / 2), looked up only there: numpy 2
#: deprecates the old name.
trapezoid = np.trapezoid if hasattr(np, "trapezoid") else np.trapz

#: Points between the bottom of an axes and the top of a legend placed under it on matplotlib < 3.7:
#: the x tick marks and labels and the x label (3.5 + 3.5 + 12 + 4 + 12 pt at the 10 pt default
#: font), plus a margin.
BELOW_AXES_PT = 40.0


def legend_below(fig, ax, *args, **kwargs):
    """A legend centred under the axes ``ax`` of ``fig``, outside them, with room made for it by
    the figure's constrained layout. matplotlib >= 3.7: ``fig.legend(loc="outside lower
    center")``, its own form; 3.6 has no "outside" locations, and there the legend belongs to
    ``ax``, anchored BELOW_AXES_PT under it (constrained layout makes room for an axes' legend
    outside it). ``args`` and ``kwargs`` are those of ``legend`` (handles, labels, ncol, ...)."""
    import matplotlib

    if tuple(int(p) for p in matplotlib.__version__.split(".")[:2]) >= (3, 7):
        return fig.legend(*args, loc="outside lower center", **kwargs)
    from matplotlib.transforms import offset_copy

    return ax.legend(*args, loc="upper center", bbox_to_anchor=(0.5, 0.0),
                     bbox_transform=offset_copy(ax.transAxes, fig=fig, y=-BELOW_AXES_PT, units="points"), **kwargs)
