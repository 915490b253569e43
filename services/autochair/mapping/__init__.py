"""Mapping: log-odds occupancy grid and a world-frame point cloud from scans and odometry."""
