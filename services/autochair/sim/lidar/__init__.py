"""The simulated Hokuyo URG-04LX: SCIP 2.0 on a pty, ray-cast in the world."""
