"""Localization: scan matching on a map fused with odometry; mapping with loop closure."""
