"""Velocity PID: desired (v, ω) and measured odometry to joystick voltages."""
