"""Auto-tune of the velocity loops: relay and step probes, SOPDT fit, gain rules."""
