"""Sessions for people's tools (CLI, monitor): a Zenoh client of the hub."""

from __future__ import annotations

import zenoh

from .config import ConfigError, load_zenoh


def open_client(connect: str | None = None, config: str | None = None,
                timeout_ms: int = 3000) -> zenoh.Session:
    """A client session to the hub; ConfigError (one line) when the hub cannot be reached."""
    settings = load_zenoh(config, connect)
    settings.mode, settings.listen = "client", []
    cfg = settings.to_zenoh()
    cfg.insert_json5("connect/timeout_ms", str(timeout_ms))
    cfg.insert_json5("connect/exit_on_failure", "true")
    try:
        return zenoh.open(cfg)
    except zenoh.ZError:
        raise ConfigError(
            f"no autochair hub at {', '.join(settings.connect)} (is `autochair up` running? "
            "set --connect or AUTOCHAIR_CONNECT)") from None


def alive_services(session: zenoh.Session, timeout_s: float = 1.0) -> set[str]:
    """Names of the services whose liveliness token is up."""
    names: set[str] = set()
    for reply in session.liveliness().get("autochair/alive/*", timeout=timeout_s):
        if reply.ok is not None:
            names.add(str(reply.ok.key_expr).rsplit("/", 1)[-1])
    return names
