"""Field operations: a field (boundary.py), its coverage plan, and what working it costs. No ROS;
the geometry is shapely's, the projection pyproj's."""
