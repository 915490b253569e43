"""E-stop: the latch that any part of the system can set and only an explicit release clears."""
