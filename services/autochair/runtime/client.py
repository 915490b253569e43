"""Sessions for people's tools (CLI, monitor): a Zenoh client of the hub."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

import msgspec
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


T = TypeVar("T", bound=msgspec.Struct)
R = TypeVar("R", bound=msgspec.Struct)


class RequestError(Exception):
    """A request got no reply, or an error reply; the message is one line for a person."""


def request(session: zenoh.Session, topic: Any, req: msgspec.Struct, reply: type[R],
            timeout_s: float = 3.0) -> R:
    """Ask a `kind="query"` row of the key table (a `Node.serve` answers): `req` must be the
    row's request type and `reply` its reply type. RequestError when no service answers in
    `timeout_s`, or it answers with an error."""
    if topic.kind != "query" or topic.reply is not reply or not isinstance(req, topic.type):
        raise TypeError(f"{topic.key} takes {topic.type.__name__} → "
                        f"{getattr(topic.reply, '__name__', None)}")
    for r in session.get(topic.key, payload=msgspec.msgpack.encode(req), timeout=timeout_s):
        if r.ok is not None:
            return msgspec.msgpack.decode(r.ok.payload.to_bytes(), type=reply)
        why = r.err.payload.to_string() if r.err is not None else "error reply"
        raise RequestError(f"{topic.key}: {why}")
    raise RequestError(f"no reply on {topic.key} within {timeout_s:g} s: is the service that "
                       "answers it running? (`autochair status`)")


def subscribe(session: zenoh.Session, topic: Any, on_msg: Callable[[T], None],
              key: str | None = None) -> zenoh.Subscriber[None]:
    """Typed subscription for people's tools: decodes a key-table row's messages and skips
    malformed payloads (the CLI must not die on someone else's bad sample)."""
    decoder = msgspec.msgpack.Decoder(topic.type)

    def on_sample(sample: zenoh.Sample) -> None:
        try:
            msg = decoder.decode(sample.payload.to_bytes())
        except (msgspec.DecodeError, msgspec.ValidationError):
            return
        on_msg(msg)

    return session.declare_subscriber(key or topic.key, on_sample)


def alive_services(session: zenoh.Session, timeout_s: float = 1.0) -> set[str]:
    """Names of the services whose liveliness token is up."""
    names: set[str] = set()
    for reply in session.liveliness().get("autochair/alive/*", timeout=timeout_s):
        if reply.ok is not None:
            names.add(str(reply.ok.key_expr).rsplit("/", 1)[-1])
    return names


def pid_caps(session: zenoh.Session, timeout_s: float = 1.5) -> tuple[float, float, float] | None:
    """The velocity PID's absolute caps (forward m/s, reverse m/s, |ω| rad/s) from its health,
    or None when no PID reports within `timeout_s` (health comes once a second)."""
    import threading

    from autochair_msgs import Health, keys

    got: list[Health] = []
    done = threading.Event()

    def on_health(h: Health) -> None:
        if "v_max_fwd_mps" in h.thresholds and not got:
            got.append(h)
            done.set()

    sub = subscribe(session, keys.HEALTH, on_health, keys.HEALTH.for_service("pid"))
    try:
        done.wait(timeout_s)
    finally:
        sub.undeclare()
    if not got:
        return None
    t = got[0].thresholds
    return t["v_max_fwd_mps"], t.get("v_max_rev_mps", 0.0), t.get("omega_max_radps", 0.0)
