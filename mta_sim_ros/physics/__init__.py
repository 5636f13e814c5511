"""The physics: train and scene spec, kinematic chain, dynamics by both of the article's
algorithms, force laws, steering actuator, validity guards. Imports numpy only (no ROS)."""
