"""Hokuyo lidar: SCIP 2.0 ingest (`node`), its pure core (`core`) and a simulated URG-04LX."""
