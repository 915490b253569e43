"""Pure gateway logic: frames in, samples out; commands in, safe joystick frames out.

The output is exactly neutral at start, while the e-stop is latched or its heartbeat is missing,
whenever no valid command arrived within the stale timeout, and whenever a command is not
enabled; otherwise it is clamped to the valid window.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from autochair.protocol import arduino
from autochair.protocol.arduino import Command, FrameDecoder, Telemetry

NEUTRAL_V = 2.5


@dataclass(frozen=True)
class Output:
    longitudinal_v: float
    angular_v: float
    enable: bool
    reason: str
    clamped: bool = False


NEUTRAL_STARTUP = Output(NEUTRAL_V, NEUTRAL_V, False, "neutral:startup")


@dataclass
class GatewayCore:
    stale_s: float = 0.1
    estop_stale_s: float = 0.5
    require_estop: bool = True  # no e-stop heartbeat → neutral (a dead e-stop must stop the chair)
    min_v: float = 1.1
    max_v: float = 3.9
    decoder: FrameDecoder = field(default_factory=FrameDecoder)
    dropped: int = 0  # telemetry frames lost (sequence gaps)
    clamped: int = 0
    skew_s: float = 0.1  # commands stamped further ahead than this are rejected
    rejected: int = 0  # commands with non-finite values
    rejected_age: int = 0  # commands stamped too long ago or in the future
    _last_seq: int | None = None
    _cmd: tuple[float, float, bool, int] | None = None
    _cmd_t: float = -math.inf
    _estop_latched: bool = False
    _estop_t: float = -math.inf
    _tx_seq: int = 0
    _ack_seq: int = 0
    # The serial link: frames go out when the output changes and at least every keepalive_s
    # (the firmware's watchdog neutralises after 200 ms of silence); a port with no telemetry
    # for rx_stall_s is reopened.
    keepalive_s: float = 0.02
    rx_stall_s: float = 2.0
    _sent: Output | None = None
    _sent_t: float = -math.inf
    # The period at which the node calls `due` (its watchdog tick). A command or heartbeat
    # that would be stale before the next tick counts as stale now, so neutral is written no
    # later than stale_s (estop_stale_s) after the last one, whatever the tick; 0: exact.
    tick_s: float = 0.0
    # A parked chair's telemetry (no motion, output not enabled, for hold_s) is passed on
    # every parked_period_s, not at the frame rate: absolute counters and the MCU clock lose
    # nothing in between, and the whole chain downstream idles at 20 Hz instead of the
    # frame rate (keys.DRIVE_RATE_HZ).
    parked_period_s: float = 0.05
    hold_s: float = 1.0
    _passed: tuple[int, int, int] | None = None  # (left, right, status) last passed on
    _passed_t: float = -math.inf
    _busy_until: float = -math.inf
    # What was written is reported (keys.JOYSTICK_OUT) when it changes, else every report_s.
    report_s: float = 0.1
    _reported: Output | None = None
    _reported_t: float = -math.inf
    _rx_t: float = -math.inf

    def on_bytes(self, data: bytes) -> list[tuple[Telemetry, int]]:
        """Decode serial bytes; returns each telemetry frame with the count of frames missed."""
        out = []
        for frame in self.decoder.feed(data):
            if not isinstance(frame, Telemetry):
                continue  # a host frame echoed back would be a wiring fault; the decoder counts it
            gap = 0 if self._last_seq is None else arduino.seq_gap(self._last_seq, frame.seq)
            if gap > 1000:  # far jump: the MCU rebooted, not a loss
                gap = 0
            self.dropped += gap
            self._last_seq = frame.seq
            self._ack_seq = frame.seq
            out.append((frame, gap))
        return out

    def on_command(self, longitudinal_v: float, angular_v: float, enable: bool,
                   now_s: float, source_seq: int = -1, age_s: float = 0.0) -> bool:
        """Accept a joystick command at monotonic time `now_s`; False if it is unusable.

        `source_seq` is the telemetry frame the command was computed from; it goes back to the
        chair as `ack_seq`, so a round trip can be timed on the wire. `age_s` is now minus the
        command's own stamp (Unix clock): a command older than the stale timeout (a delayed or
        replayed one) or stamped in the future beyond `skew_s` is refused.
        """
        if not (math.isfinite(longitudinal_v) and math.isfinite(angular_v)):
            self.rejected += 1
            return False
        if not -self.skew_s <= age_s <= self.stale_s:
            self.rejected_age += 1
            return False
        self._cmd = (longitudinal_v, angular_v, enable, source_seq)
        self._cmd_t = now_s
        return True

    def on_estop(self, latched: bool, now_s: float) -> None:
        self._estop_latched, self._estop_t = latched, now_s

    def on_estop_gone(self) -> None:
        """The e-stop service's liveliness token vanished (it died): treat it as silent now,
        instead of waiting out the heartbeat timeout."""
        self._estop_t = -math.inf

    def reset(self) -> None:
        """Forget the last command (e.g. after a reconnect): output goes neutral until a new one."""
        self._cmd, self._cmd_t, self._last_seq = None, -math.inf, None

    def link_up(self, now_s: float) -> None:
        """A port was (re)opened: nothing carries over from the old link."""
        self.reset()
        self._sent, self._rx_t = None, now_s

    def due(self, now_s: float) -> Output | None:
        """The output to write now: when it changed or the keepalive is due, else None."""
        out = self.output(now_s)
        if out != self._sent or now_s - self._sent_t >= self.keepalive_s:
            return out
        return None

    def sent(self, out: Output, now_s: float) -> tuple[bool, bool, bool]:
        """`out` was written: (its reason changed, the new reason is a fault, report it).
        Neutral because nothing is asked (startup, parked) is normal; any other neutral is a
        fault. A frame is reported when it differs from the last reported or report_s after
        it: a parked chair's identical neutral frames are not a record per frame."""
        changed = self._sent is None or out.reason != self._sent.reason
        self._sent, self._sent_t = out, now_s
        report = out != self._reported or now_s - self._reported_t >= self.report_s
        if report:
            self._reported, self._reported_t = out, now_s
        return changed, out.reason not in ("command", "neutral:startup", "neutral:disabled"), \
            report

    def pass_on(self, frame: Telemetry, gap: int, now_s: float) -> bool:
        """Whether to publish this telemetry frame: always while the chair moves, the output
        is enabled or frames were lost, and for hold_s after; parked, one per
        parked_period_s."""
        seen = (frame.left, frame.right, frame.status)
        if gap or seen != self._passed or (self._sent is not None and self._sent.enable):
            self._busy_until = now_s + self.hold_s
        if now_s < self._busy_until or now_s - self._passed_t >= self.parked_period_s:
            self._passed, self._passed_t = seen, now_s
            return True
        return False

    def received(self, frames: int, now_s: float) -> bool:
        """Telemetry arrived (`frames` decoded); True when the link has been silent for
        rx_stall_s and must be reopened."""
        if frames:
            self._rx_t = now_s
        return now_s - self._rx_t > self.rx_stall_s

    def output(self, now_s: float) -> Output:
        if self._estop_latched:
            return Output(NEUTRAL_V, NEUTRAL_V, False, "neutral:estop")
        ahead = now_s + self.tick_s  # when the next tick would look
        if self.require_estop and ahead - self._estop_t > self.estop_stale_s:
            return Output(NEUTRAL_V, NEUTRAL_V, False, "neutral:estop_silent")
        if self._cmd is None:
            return NEUTRAL_STARTUP
        if ahead - self._cmd_t > self.stale_s:
            return Output(NEUTRAL_V, NEUTRAL_V, False, "neutral:stale")
        lon, ang, enable, _ = self._cmd
        if not enable:
            return Output(NEUTRAL_V, NEUTRAL_V, False, "neutral:disabled")
        clon, cang = min(max(lon, self.min_v), self.max_v), min(max(ang, self.min_v), self.max_v)
        clamped = (clon, cang) != (lon, ang)
        return Output(clon, cang, True, "command", clamped)

    def frame(self, out: Output) -> tuple[bytes, int]:
        """The next host frame for `out`, and its sequence number."""
        seq = self._tx_seq
        self._tx_seq = (seq + 1) & 0xFFFF
        if out.clamped:
            self.clamped += 1
        ack = self._ack_seq
        if out.reason == "command" and self._cmd is not None and self._cmd[3] >= 0:
            ack = self._cmd[3]
        cmd = Command(seq=seq, ack_seq=ack,
                      longitudinal_mv=round(out.longitudinal_v * 1000),
                      angular_mv=round(out.angular_v * 1000),
                      flags=arduino.FL_ENABLE if out.enable else 0)
        return arduino.encode(cmd), seq
