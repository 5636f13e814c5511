"""The physics: train and scene spec and loader, kinematic chain, dynamics by both of the article's
algorithms, the three fidelity levels behind one interface (levels.py), the compiled kernel that
writes each law once (kernel/), validity guards. Imports numpy and numba only (no ROS)."""
