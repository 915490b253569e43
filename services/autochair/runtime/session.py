"""Every Zenoh session of autochair opens here: services, the hub, the launcher, people's tools,
tests and benches. The returned `zenoh.Session` is a context manager (`with open_session(...)
as s:` closes it).

Zenoh's own log is initialised once per process, from $RUST_LOG when set, else at `log_level`:
"warn" for services and the hub (TLS handshakes, ACL and certificate refusals show in their
logs), "error" for people's tools (a one-line error of ours explains an unreachable hub).
"""

from __future__ import annotations

import json
import threading

import zenoh

from .config import ConfigError, ZenohSettings

_log_lock = threading.Lock()
_log_ready = False


def init_zenoh_log(level: str) -> None:
    """Zenoh's log, once per process ($RUST_LOG wins over `level`)."""
    global _log_ready
    with _log_lock:
        if not _log_ready:
            zenoh.init_log_from_env_or(level)
            _log_ready = True


def open_session(settings: ZenohSettings | zenoh.Config, *, client_timeout_ms: int | None = None,
                 log_level: str = "warn", unreachable: str = "") -> zenoh.Session:
    """A Zenoh session from our settings (or a ready Config, e.g. a test's TLS profile).

    `client_timeout_ms`: a client that cannot reach its router within this fails at once (not
    retried in the background). Failure is a one-line ConfigError: `unreachable` when given
    (what a person should do), else Zenoh's reason.
    """
    init_zenoh_log(log_level)
    cfg = settings.to_zenoh() if isinstance(settings, ZenohSettings) else settings
    if client_timeout_ms is not None:
        cfg.insert_json5("connect/timeout_ms", json.dumps(client_timeout_ms))
        cfg.insert_json5("connect/exit_on_failure", "true")
    try:
        return zenoh.open(cfg)
    except zenoh.ZError as e:
        why = unreachable or "cannot open a Zenoh session: {reason}"
        raise ConfigError(why.replace("{reason}", str(e))) from None


def client_settings(hub: str, chair: str = "", config_file: str = "") -> ZenohSettings:
    """A client of the hub at `hub` in chair `chair`'s namespace ("" = none)."""
    return ZenohSettings(mode="client", connect=[hub] if hub else [], listen=[],
                         namespace=chair, config_file=config_file)
