"""The simulators: the chair with its Arduino, and the Hokuyo, in one world."""
