"""Emulation of the Arduino firmware's side of the protocol (pure: time is passed in).

Per tick the firmware reads host bytes (Command frames), decides the two joystick voltages it
drives, and emits one Telemetry frame. Rules (docs/arduino-protocol.md, "Timing"):

- for the first `boot_s` (1 s) after reset the output is neutral and ST_BOOT is set;
  commands are parsed and count as host contact but are not applied;
- a Command with FL_ENABLE and both voltages inside [1100, 3900] mV is applied
  (ST_OUTPUT_ENABLED); out of the window -> neutral and ST_CMD_REJECTED; enable clear ->
  neutral;
- no valid host frame for `watchdog_s` (200 ms) -> neutral and ST_HOST_TIMEOUT;
- telemetry: u16 seq (+1 per frame, wrapping), u32 µs clock, u32 counters.

Use: `fw.receive(host_bytes, now_s)`, `model.step(*fw.output_volts, dt)`,
`wire = fw.tick(now_s, model.left_counts, model.right_counts)`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from autochair.protocol import arduino as proto

NEUTRAL_MV = 2500
MIN_MV = 1100
MAX_MV = 3900


@dataclass
class FirmwareCounters:
    host_frames: int = 0  # valid Command frames received
    host_bad_frames: int = 0  # rejected frames (CRC, COBS, length, type, oversize)
    host_timeouts: int = 0  # transitions into ST_HOST_TIMEOUT after host contact
    rejected_commands: int = 0  # valid frames with voltages outside the window
    telemetry_frames: int = 0


@dataclass
class Firmware:
    boot_s: float = 1.0
    watchdog_s: float = 0.2
    seq_start: int = 0  # for wrap tests
    clock_offset_us: int = 0  # MCU clock at reset, for wrap tests
    counters: FirmwareCounters = field(default_factory=FirmwareCounters)
    longitudinal_mv: int = NEUTRAL_MV
    angular_mv: int = NEUTRAL_MV
    status: int = proto.ST_BOOT | proto.ST_HOST_TIMEOUT
    last_ack_seq: int = -1  # host's last ack_seq (what the host had seen of our telemetry)
    _decoder: proto.FrameDecoder = field(default_factory=proto.FrameDecoder)
    _last_host_s: float | None = None
    _seq: int = -1
    _timed_out: bool = True

    @property
    def output_volts(self) -> tuple[float, float]:
        """Joystick voltages (longitudinal, angular) currently driven, in volts."""
        return self.longitudinal_mv / 1000.0, self.angular_mv / 1000.0

    def _neutral(self) -> None:
        self.longitudinal_mv = self.angular_mv = NEUTRAL_MV
        self.status &= ~proto.ST_OUTPUT_ENABLED

    def receive(self, data: bytes, now_s: float) -> None:
        """Bytes from the host, arrived at sim time `now_s` (seconds since reset)."""
        frames = self._decoder.feed(data)
        self.counters.host_bad_frames = self._decoder.stats.bad_frames
        for frame in frames:
            if isinstance(frame, proto.Command):
                self._command(frame, now_s)
            else:  # a Telemetry frame sent to us: valid CRC, wrong direction
                self.counters.host_bad_frames += 1
                self._decoder.stats.unknown_type += 1

    def _command(self, cmd: proto.Command, now_s: float) -> None:
        self.counters.host_frames += 1
        self._last_host_s = now_s
        self.last_ack_seq = cmd.ack_seq
        if now_s < self.boot_s:
            return
        in_window = all(MIN_MV <= mv <= MAX_MV for mv in (cmd.longitudinal_mv, cmd.angular_mv))
        if not in_window:
            self.counters.rejected_commands += 1
            self.status |= proto.ST_CMD_REJECTED
            self._neutral()
            return
        self.status &= ~proto.ST_CMD_REJECTED
        if cmd.enable:
            self.longitudinal_mv, self.angular_mv = cmd.longitudinal_mv, cmd.angular_mv
            self.status |= proto.ST_OUTPUT_ENABLED
        else:
            self._neutral()

    def watch(self, now_s: float) -> None:
        """Apply the boot and watchdog rules at `now_s` (the firmware does so every tick and
        in mid-frame)."""
        if now_s < self.boot_s:
            self.status |= proto.ST_BOOT
            self._neutral()
        else:
            self.status &= ~proto.ST_BOOT
        timed_out = self._last_host_s is None or now_s - self._last_host_s > self.watchdog_s
        if timed_out:
            if not self._timed_out and self._last_host_s is not None:
                self.counters.host_timeouts += 1
            self.status |= proto.ST_HOST_TIMEOUT
            self._neutral()
        else:
            self.status &= ~proto.ST_HOST_TIMEOUT
        self._timed_out = timed_out

    def tick(self, now_s: float, left_counts: int, right_counts: int) -> bytes:
        """Apply boot and watchdog rules at `now_s`, return one encoded Telemetry frame."""
        self.watch(now_s)
        self._seq = (self.seq_start if self._seq < 0 else self._seq + 1) & 0xFFFF
        self.counters.telemetry_frames += 1
        t_us = (self.clock_offset_us + round(now_s * 1e6)) & 0xFFFFFFFF
        return proto.encode(proto.Telemetry(self._seq, t_us, left_counts & 0xFFFFFFFF,
                                            right_counts & 0xFFFFFFFF, self.status))
