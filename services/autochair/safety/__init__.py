"""Safety monitor: obstacle slow-down and stop from the laser scan."""
