"""People in the laser scans: moving obstacles for MPEPC (a pure tracker; see core.py)."""
