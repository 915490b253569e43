"""Odometry: encoder counts to pose and velocity."""
