"""The link of the CLI's tools to a chair (status, drive, monitor, teleop, foxglove, ...).

`--zenoh-config FILE` (or $AUTOCHAIR_ZENOH_CONFIG) is a laptop profile from `autochair certs`
(client over mutual TLS); without it, a plain client of `--connect` / $AUTOCHAIR_CONNECT.
`--chair NAME` (or $AUTOCHAIR_CHAIR, or [zenoh] namespace of $AUTOCHAIR_CONFIG) picks the chair:
the session joins its Zenoh namespace, so every key the tool uses is that chair's.
"""

from __future__ import annotations

import argparse
import os
from typing import Any, TypeVar

import msgspec
import zenoh

from autochair.cli import CliError
from autochair.runtime.client import open_client, request
from autochair.runtime.config import ENV_CHAIR, ConfigError, check_chair

R = TypeVar("R", bound=msgspec.Struct)

ENV_ZENOH_CONFIG = "AUTOCHAIR_ZENOH_CONFIG"


def add_chair_arg(p: argparse.ArgumentParser, what: str = "the chair to talk to",
                  default: str = f"${ENV_CHAIR}, else [zenoh] namespace of the config, else "
                  "none") -> None:
    p.add_argument("--chair", metavar="NAME",
                   help=f"{what}: its Zenoh namespace, NAME/autochair/... (default {default})")


def add_link_args(p: argparse.ArgumentParser, **chair: str) -> None:
    """--connect, --zenoh-config and --chair (`chair`: add_chair_arg's what and default)."""
    p.add_argument("--connect", help="Zenoh endpoint of the chair's hub "
                   "(default $AUTOCHAIR_CONNECT or tcp/127.0.0.1:7447)")
    p.add_argument("--zenoh-config", default=os.environ.get(ENV_ZENOH_CONFIG),
                   help=f"laptop Zenoh profile (TLS) made by `autochair certs` "
                   f"(default ${ENV_ZENOH_CONFIG})")
    add_chair_arg(p, **chair)


def chair_arg(args: argparse.Namespace) -> str | None:
    """The --chair given (validated), or None when not given."""
    chair: str | None = getattr(args, "chair", None)
    if chair is None or chair == "":
        return chair
    try:
        return check_chair(chair)
    except ConfigError as e:
        raise CliError(str(e)) from None


def tool_session(args: argparse.Namespace, timeout_ms: int = 5000,
                 chair: str | None = None) -> zenoh.Session:
    """The tool's client session (a context manager); `chair` (else --chair) overrides the
    chair ("" = none). Failures are one-line CliErrors."""
    try:
        return open_client(args.connect, timeout_ms=timeout_ms,
                           chair=chair if chair is not None else chair_arg(args),
                           zenoh_config=args.zenoh_config or "")
    except ConfigError as e:
        raise CliError(str(e)) from None


def ask(args: argparse.Namespace, topic: Any, req: msgspec.Struct, reply: type[R]) -> R:
    """One request from a tool: a session for it, the reply, and a refusal (`ok` false) as
    the reply's own one-line error."""
    session = tool_session(args)
    try:
        got = request(session, topic, req, reply)
    finally:
        session.close()
    if not getattr(got, "ok", True):
        raise CliError(getattr(got, "error", "refused"))
    return got
