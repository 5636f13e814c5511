"""Synthesis sweeps: many hitching schemes run and compared (spec.py: what varies; engine.py: the
runs, serially or on Dask; report.py: Pareto fronts, Sobol indices, the best schemes). No ROS here."""
