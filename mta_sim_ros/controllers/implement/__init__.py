"""Working a field plan closed loop, offline: a controller that keeps the implement's working point
on the plan's route (``design.py``), the whole run in one compiled call (``loop.py``), and its set-up
and trace (``drive.py``). No ROS."""
