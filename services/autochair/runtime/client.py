"""Sessions for people's tools (CLI, monitor): a Zenoh client of the hub."""

from __future__ import annotations

import struct
import threading
import time
from collections.abc import Callable
from typing import Any, TypeVar

import msgspec
import zenoh

from autochair_msgs import keys

from .config import load_zenoh
from .session import open_session


def open_client(connect: str | None = None, config: str | None = None,
                timeout_ms: int = 3000, chair: str | None = None,
                zenoh_config: str = "") -> zenoh.Session:
    """A client session to the hub, in chair `chair`'s namespace (None: $AUTOCHAIR_CHAIR, else
    the config's [zenoh] namespace; "": none); `zenoh_config`: a laptop's Zenoh profile (TLS)
    from `autochair certs`. ConfigError (one line) when the name is not a chair name or the hub
    cannot be reached."""
    settings = load_zenoh(config, connect, chair)
    settings.mode, settings.listen = "client", []
    if zenoh_config:
        settings.config_file = zenoh_config
        settings.connect = [connect] if connect else []  # else the profile's endpoints
        why = f"cannot reach the chair with {zenoh_config}: {{reason}}"
    else:
        why = (f"no autochair hub at {', '.join(settings.connect)} (is `autochair up` running? "
               "set --connect or AUTOCHAIR_CONNECT)")
    return open_session(settings, client_timeout_ms=timeout_ms, log_level="error",
                        unreachable=why)


T = TypeVar("T", bound=msgspec.Struct)
R = TypeVar("R", bound=msgspec.Struct)
ENCODER = msgspec.msgpack.Encoder()  # one encoder, built once, for every publisher


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
    for r in session.get(topic.key, payload=ENCODER.encode(req), timeout=timeout_s,
                         attachment=deadline(time.time_ns(), timeout_s)):
        if r.ok is not None:
            return msgspec.msgpack.decode(r.ok.payload.to_bytes(), type=reply)
        why = r.err.payload.to_string() if r.err is not None else "error reply"
        raise RequestError(f"{topic.key}: {why}")
    raise RequestError(f"no reply on {topic.key} within {timeout_s:g} s: is the service that "
                       "answers it running? (`autochair status`)")


def deadline(sent_ns: int, timeout_s: float) -> bytes:
    """A request's attachment: when it was sent and when its asker stops waiting (Unix ns)."""
    return struct.pack("<qq", sent_ns, sent_ns + round(timeout_s * 1e9))


def too_late(attachment: bytes | None, now_ns: int, skew_s: float) -> str:
    """"" if a request may be acted on now, else why not (one line). A request that arrives
    after its asker gave up is not acted on: the person was told it failed, and a goal or a
    release delivered late (a stalled link, a busy service) would start motion nobody is
    waiting for. Nor is one stamped further ahead than the clock skew allowed for commands
    (its deadline cannot be trusted), or one that carries no deadline."""
    if attachment is None or len(attachment) != 16:
        return "it carries no deadline (send it with autochair's runtime.client.request)"
    sent_ns, until_ns = struct.unpack("<qq", attachment)
    if sent_ns - now_ns > skew_s * 1e9:
        return (f"it is stamped {(sent_ns - now_ns) / 1e9:.2f} s ahead of this clock "
                f"(allowed {skew_s:g} s): are the clocks synchronised?")
    if now_ns > until_ns:
        return (f"it arrived {(now_ns - until_ns) / 1e9:.2f} s after its asker stopped "
                f"waiting ({(now_ns - sent_ns) / 1e9:.2f} s after it was sent)")
    return ""


def _decoding(topic: Any, handle: Callable[[zenoh.Sample, T], None],
              on_error: Callable[[], None] | None = None) -> Callable[[zenoh.Sample], None]:
    """A sample callback that decodes a key-table row's message and skips malformed payloads
    (a person's tool must not die on someone else's bad sample), calling `on_error` for each."""
    decoder = msgspec.msgpack.Decoder(topic.type)

    def on_sample(sample: zenoh.Sample) -> None:
        try:
            msg = decoder.decode(sample.payload.to_bytes())
        except (msgspec.DecodeError, msgspec.ValidationError):
            if on_error is not None:
                on_error()
            return
        handle(sample, msg)

    return on_sample


def subscribe(session: zenoh.Session, topic: Any, on_msg: Callable[[T], None],
              key: str | None = None, on_error: Callable[[], None] | None = None
              ) -> zenoh.Subscriber[None]:
    """Typed subscription for people's tools; malformed payloads are skipped (`on_error`)."""

    def forward(_: zenoh.Sample, msg: T) -> None:
        on_msg(msg)

    return session.declare_subscriber(key or topic.key, _decoding(topic, forward, on_error))


class Publisher:
    """A typed publisher of one key-table row (services' `Node.publisher` and people's tools):
    `put` encodes. express: send at once instead of batching; reliable: block instead of
    dropping under congestion. `stopping`: once set, a put racing shutdown (the session
    closing) is not an error."""

    def __init__(self, session: zenoh.Session, topic: Any, key: str | None = None, *,
                 express: bool = False, reliable: bool = False,
                 stopping: threading.Event | None = None) -> None:
        self._pub = session.declare_publisher(
            key or topic.key, express=express,
            congestion_control=(zenoh.CongestionControl.BLOCK if reliable
                                else zenoh.CongestionControl.DROP),
            reliability=zenoh.Reliability.RELIABLE)
        self._stopping = stopping

    def put(self, msg: msgspec.Struct) -> None:
        self.put_raw(ENCODER.encode(msg))

    def put_raw(self, payload: bytes) -> None:
        """An already encoded message (a replay's recorded bytes)."""
        try:
            self._pub.put(payload)
        except zenoh.ZError:
            if self._stopping is None or not self._stopping.is_set():
                raise

    def undeclare(self) -> None:
        self._pub.undeclare()


def declare_alive(session: zenoh.Session, service: str) -> zenoh.LivelinessToken:
    """The liveliness token that says `service` is up (a Node's own; tests fake a service)."""
    return session.liveliness().declare_token(f"{keys.PREFIX}/alive/{service}")


def watch_alive(session: zenoh.Session, on_change: Callable[[str, bool], None],
                service: str = "*") -> zenoh.Subscriber[None]:
    """`on_change(service, alive)` whenever a liveliness token of this chair's `service`
    ("*": any) appears or vanishes, starting with those already up."""
    def on_token(sample: zenoh.Sample) -> None:
        on_change(str(sample.key_expr).rsplit("/", 1)[-1], sample.kind == zenoh.SampleKind.PUT)

    return session.liveliness().declare_subscriber(f"{keys.PREFIX}/alive/{service}", on_token,
                                                   history=True)


def alive_services(session: zenoh.Session, timeout_s: float = 1.0) -> set[str]:
    """Names of the services whose liveliness token is up (in the session's chair)."""
    names: set[str] = set()
    for reply in session.liveliness().get(keys.ALIVE, timeout=timeout_s):
        if reply.ok is not None:
            names.add(str(reply.ok.key_expr).rsplit("/", 1)[-1])
    return names


def _in_every_chair(key: str) -> tuple[str, str]:
    """The key expressions of a row in every chair a session can see: its own namespace (or
    none) and one namespace down. Two expressions, not `**/...`: the hub's ACL allows laptops
    exactly `autochair/...` and `*/autochair/...`, and a query must be included in a rule."""
    return key, f"*/{key}"


def chair_of(key: str, row: str) -> str:
    """The chair part of a concrete `key` of table row `row` (a key expression of fixed depth)
    seen through `_in_every_chair`: "" for `autochair/...` (the session's own namespace, or
    none), "NAME" for `NAME/autochair/...` (even a chair named "autochair")."""
    chunks = key.split("/")
    return chunks[0] if len(chunks) > row.count("/") + 1 else ""


def alive_chairs(session: zenoh.Session, timeout_s: float = 1.0) -> dict[str, set[str]]:
    """Every chair this session can see, with its live services (liveliness tokens). Seen from
    a session without a namespace, a chair without one is "" and chair NAME (its services'
    namespace) is "NAME"; a session in chair NAME's namespace sees only that chair, as ""."""
    chairs: dict[str, set[str]] = {}
    asks = [session.liveliness().get(k, timeout=timeout_s) for k in _in_every_chair(keys.ALIVE)]
    for replies in asks:  # asked together: one timeout, not two
        for reply in replies:
            if reply.ok is not None:
                key = str(reply.ok.key_expr)
                chairs.setdefault(chair_of(key, keys.ALIVE), set()).add(
                    key.rsplit("/", 1)[-1])
    return chairs


def subscribe_chairs(session: zenoh.Session, topic: Any, on_msg: Callable[[str, T], None],
                     ) -> list[zenoh.Subscriber[None]]:
    """`subscribe` to a row in every chair the session can see: `on_msg` gets the chair (as in
    `alive_chairs`) and the decoded message; malformed payloads are skipped."""
    def forward(sample: zenoh.Sample, msg: T) -> None:
        on_msg(chair_of(str(sample.key_expr), topic.key), msg)

    on_sample = _decoding(topic, forward)
    return [session.declare_subscriber(k, on_sample) for k in _in_every_chair(topic.key)]


def pid_caps(session: zenoh.Session, timeout_s: float = 1.5) -> tuple[float, float, float] | None:
    """The velocity PID's absolute caps (forward m/s, reverse m/s, |ω| rad/s) from its health,
    or None when no PID reports within `timeout_s` (health comes once a second)."""
    from autochair_msgs import Health

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


# A stream's command reaches the PID and is taken within this (the drive chain's 20-100 Hz):
# before it, the PID's status still says why it held the stream before.
PID_TAKES_NS = 200_000_000


def pid_hold(inhibit: str, status_ns: int, stream_start_ns: int) -> str:
    """Why the velocity PID holds a tool's stream begun at `stream_start_ns` (its status's
    `inhibit`, stamped `status_ns`): "" while it obeys, before it has had PID_TAKES_NS to take
    the stream, or without a stream (0)."""
    fresh = stream_start_ns > 0 and status_ns > stream_start_ns + PID_TAKES_NS
    return inhibit if fresh else ""


def answer_hub_probe(session: zenoh.Session) -> zenoh.Queryable[None]:
    """The hub's own queryable (keys.HUB_PROBE): an empty reply to every ask."""
    return session.declare_queryable(keys.HUB_PROBE, lambda q: q.reply(q.key_expr, b""))


def hub_answers(session: zenoh.Session, timeout_s: float) -> bool:
    """Whether the hub answered its probe through this session's link within `timeout_s`."""
    return any(r.ok is not None for r in list(session.get(keys.HUB_PROBE, timeout=timeout_s)))
