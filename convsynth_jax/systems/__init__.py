"""Speech-driven synthesis systems: the shared interface (base.py) and the registered systems."""
