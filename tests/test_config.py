"""Service configs are declarative: a bad value is a one-line error naming the section and the
field (msgspec constraints), for every service the runtime loads."""

from __future__ import annotations

import pytest

from autochair.control.core import ControlConfig
from autochair.estop.node import EStopConfig
from autochair.gateway.node import GatewayConfig
from autochair.lidar.node import LidarConfig
from autochair.localization.node import LocalizationConfig
from autochair.logger.writer import LoggerConfig
from autochair.mapping.node import MappingConfig
from autochair.odometry.node import OdometryConfig
from autochair.runtime.config import ConfigError, load_section
from autochair.safety.node import SafetyConfig
from autochair.sim.chair.node import SimConfig
from autochair.sim.lidar.node import LidarSimConfig

# What a section needs besides its defaults (the simulators' pty link).
REQUIRED = {"sim": ['pty_link="/tmp/arduino"'], "lidar-sim": ['pty_link="/tmp/lidar"']}


@pytest.mark.parametrize("type_,section,override,field", [
    (GatewayConfig, "gateway", "max_v=2.0", "max_v"),  # the window must contain 2.5 V
    (GatewayConfig, "gateway", "keepalive_hz=4", "keepalive_hz"),  # slower than the watchdog
    (LidarConfig, "lidar", 'command="XX"', "command"),
    (LidarConfig, "lidar", 'url="tcp://host"', "tcp://HOST:PORT"),
    (LidarConfig, "lidar", "cluster=0", "cluster"),
    (EStopConfig, "estop", "rate_hz=0.5", "rate_hz"),
    (LoggerConfig, "logger", 'compression="gzip"', "compression"),
    (LoggerConfig, "logger", "queue_size=0", "queue_size"),
    (SafetyConfig, "safety", "decel_mps2=0", "decel_mps2"),
    (SafetyConfig, "safety", "min_valid_fraction=1.5", "min_valid_fraction"),
    (SafetyConfig, "safety", "clear_hold_s=-1", "clear_hold_s"),
    (ControlConfig, "control", "rate_hz=10", "rate_hz"),
    (OdometryConfig, "odometry", "wheel_diameter_ratio=3", "wheel_diameter_ratio"),
    (MappingConfig, "mapping", "resolution_m=0", "resolution_m"),
    (MappingConfig, "mapping", "resolution_m=0.001", "50 M cells"),
    (LocalizationConfig, "localization", "map_period_s=0", "map_period_s"),
    (SimConfig, "sim", "time_scale=0", "time_scale"),
    (LidarSimConfig, "lidar-sim", "scan_rate_hz=400", "scan_rate_hz"),
    (ControlConfig, "control", "k1=0", "k1"),
])
def test_a_bad_value_names_its_section_and_field(type_: type, section: str, override: str,
                                                 field: str) -> None:
    base = REQUIRED.get(section, [])
    load_section(type_, section, None, base)  # positive control: the defaults load
    with pytest.raises(ConfigError) as e:
        load_section(type_, section, None, [*base, override])
    msg = str(e.value)
    assert msg.startswith(f"[{section}]") and field in msg and "\n" not in msg, msg


def test_the_safety_configs_defaults_are_the_cores() -> None:
    """SafetyConfig extends the core's SafetyTuning: one place for each default."""
    from autochair.safety.core import SafetyParams, SafetyTuning

    cfg, params = SafetyConfig(), SafetyParams()
    assert all(getattr(cfg, f) == getattr(params, f) for f in SafetyTuning.__struct_fields__)


def test_the_control_configs_gains_are_the_laws() -> None:
    """ControlConfig and MPEPC's LawParams extend law.Gains: the thesis gains written once."""
    from autochair.control.law import Gains

    assert ControlConfig().gains == Gains()
    assert ControlConfig().law(0.025).k2 == Gains().k2
