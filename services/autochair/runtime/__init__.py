"""The small runtime every service shares: config, Zenoh session, node, rate loop, health."""

from .config import ChairGeometry, ConfigError, StaleConfig, ZenohSettings, load_section
from .node import Node, service_main

__all__ = ["ChairGeometry", "ConfigError", "Node", "StaleConfig", "ZenohSettings", "load_section",
           "service_main"]
