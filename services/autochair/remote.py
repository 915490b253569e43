"""A laptop's Zenoh session for the remote tools (monitor, teleop, foxglove).

`--zenoh-config FILE` (or $AUTOCHAIR_ZENOH_CONFIG) is a laptop profile from `autochair certs`
(client over mutual TLS); without it, a plain client of `--connect` / $AUTOCHAIR_CONNECT.
"""

from __future__ import annotations

import argparse
import os

import zenoh

from autochair.cli import CliError
from autochair.runtime.client import open_client
from autochair.runtime.config import ConfigError, ZenohSettings

ENV_ZENOH_CONFIG = "AUTOCHAIR_ZENOH_CONFIG"


def add_link_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--connect", help="Zenoh endpoint of the chair's hub "
                   "(default $AUTOCHAIR_CONNECT or tcp/127.0.0.1:7447)")
    p.add_argument("--zenoh-config", default=os.environ.get(ENV_ZENOH_CONFIG),
                   help=f"laptop Zenoh profile (TLS) made by `autochair certs` "
                   f"(default ${ENV_ZENOH_CONFIG})")


def open_session(args: argparse.Namespace, timeout_ms: int = 5000) -> zenoh.Session:
    try:
        if not args.zenoh_config:
            return open_client(args.connect, timeout_ms=timeout_ms)
        settings = ZenohSettings(mode="client", listen=[], config_file=args.zenoh_config,
                                 connect=[args.connect] if args.connect else [])
        cfg = settings.to_zenoh()
        cfg.insert_json5("connect/timeout_ms", str(timeout_ms))
        cfg.insert_json5("connect/exit_on_failure", "true")
        return zenoh.open(cfg)
    except ConfigError as e:
        raise CliError(str(e)) from None
    except zenoh.ZError as e:
        raise CliError(f"cannot reach the chair with {args.zenoh_config}: {e}") from None
