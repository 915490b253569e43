"""autochair: control stack of an autonomous electric wheelchair."""

__version__ = "0.1.0"
