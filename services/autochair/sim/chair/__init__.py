"""The simulated chair: its motion and its Arduino, on a pty."""
