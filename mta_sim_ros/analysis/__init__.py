"""Recorded runs read back into figures, tables and plots (``mta analyze``, and the re-simulation
of ``mta replay --resimulate``). No ROS: bags are read with the package's own decoder.

* :mod:`.bagdata`: a bag read into time series (:class:`BagData`, ``load_bag``).
* :mod:`.track_geometry`: least-squares circles, the distance of points to a polyline.
* :mod:`.measures`: the figures of one run (off-tracking, steady radii, energy balance).
* :mod:`.compare`: two runs' largest differences.
* :mod:`.tables`: every message as CSV.
* :mod:`.plots`: the PNG figures.
* :mod:`.markdown`: summary.md.
* :mod:`.bag_report`: ``analyze()``, the report folder of one or several bags.
* :mod:`.resimulation`: ``resimulate()``, a bag's commands run again and its outputs compared.
"""

from .bag_report import analyze, default_folder
from .bagdata import KNOWN, AnalyzeError, BagData, Series, last_component, load_bag, quaternion_yaw, wrap
from .compare import compare
from .track_geometry import distance_to_path, fit_circle
from .measures import energy_balance, off_tracking, steady_radii, summarize
from .plots import FIGURES, plot_all
from .resimulation import Resimulation, ResimulationError, resimulate
from .tables import csv_name, csv_rows, read_csv, write_csv

__all__ = [
    "FIGURES",
    "KNOWN",
    "AnalyzeError",
    "BagData",
    "Resimulation",
    "ResimulationError",
    "Series",
    "analyze",
    "compare",
    "csv_name",
    "csv_rows",
    "default_folder",
    "distance_to_path",
    "energy_balance",
    "fit_circle",
    "last_component",
    "load_bag",
    "off_tracking",
    "plot_all",
    "quaternion_yaw",
    "read_csv",
    "resimulate",
    "steady_radii",
    "summarize",
    "wrap",
    "write_csv",
]
