"""mta_sim_ros: tractor-train (multi-trailer) simulator for ROS 2 Jazzy."""

__version__ = "0.1.0"
