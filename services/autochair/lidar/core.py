"""Lidar ingest core, pure: SCIP session over an abstract transport, scan decoding to LaserScan,
device-clock unwrapping and offset estimation, reconnect backoff.

No serial, socket or clock imports: the node passes a `Transport` and the clocks in, so tests
can wire this straight to the simulated device (`autochair.sim.lidar.scanner.UrgDevice`).
"""

from __future__ import annotations

import enum
import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import numpy.typing as npt

from autochair.backoff import Backoff
from autochair.protocol import scip
from autochair_msgs import LaserScan

WRAP = 1 << 24  # the device clock is 24-bit milliseconds (wraps after ~4.66 h)


class Transport(Protocol):
    def write(self, data: bytes) -> None: ...

    def read(self, timeout_s: float) -> bytes:
        """Bytes within `timeout_s` (b"" if none); raises OSError when the link is gone."""
        ...

    def close(self) -> None: ...


class LidarTimeout(scip.ScipError):
    """No (valid) reply or scan within the allowed time."""


@dataclass(frozen=True)
class LaserParams:
    dmin_mm: int
    dmax_mm: int
    ares: int
    amin: int
    amax: int
    afrt: int
    scan_rpm: int
    model: str = ""

    @classmethod
    def from_pp(cls, pp: dict[str, str]) -> LaserParams:
        try:
            vals = {k: int(pp[k].split("[")[0]) for k in
                    ("DMIN", "DMAX", "ARES", "AMIN", "AMAX", "AFRT", "SCAN")}
        except KeyError as e:
            raise scip.FormatError(f"PP reply lacks {e.args[0]}") from None
        except ValueError as e:
            raise scip.FormatError(f"PP reply has a non-integer value: {e}") from None
        if not (0 <= vals["AMIN"] <= vals["AMAX"] and vals["ARES"] > 0 and vals["SCAN"] > 0
                and 0 <= vals["DMIN"] < vals["DMAX"]):
            raise scip.FormatError(f"PP values do not make sense: {vals}")
        return cls(vals["DMIN"], vals["DMAX"], vals["ARES"], vals["AMIN"], vals["AMAX"],
                   vals["AFRT"], vals["SCAN"], pp.get("MODL", ""))

    @property
    def period_ms(self) -> float:
        return 60000.0 / self.scan_rpm


class Unwrapper:
    """24-bit device ms to a monotonic count (modular difference, like encoder counters)."""

    def __init__(self) -> None:
        self.last_raw: int | None = None
        self.value = 0

    def update(self, raw: int) -> tuple[int, int]:
        """(unwrapped ms, delta ms since the previous sample; 0 for the first)."""
        if self.last_raw is None:
            self.last_raw, self.value = raw, raw
            return raw, 0
        delta = ((raw - self.last_raw + WRAP // 2) % WRAP) - WRAP // 2
        self.last_raw = raw
        self.value += delta
        return self.value, delta


class ClockSync:
    """Device ms → host ns: offset = min over a window of (host_rx − device_time).

    The minimum is the sample with the least transport/scheduling latency, so latency spikes do
    not move it; the window lets it follow clock drift. The device stamps a scan when it starts
    and sends it one period later, so that period is taken off.
    """

    def __init__(self, window: int = 100, period_ns: int = 0) -> None:
        self.samples: deque[int] = deque(maxlen=window)
        self.period_ns = period_ns

    def reset(self) -> None:
        self.samples.clear()

    def update(self, device_ms: int, host_rx_ns: int) -> int:
        self.samples.append(host_rx_ns - device_ms * 1_000_000)
        return self.to_host_ns(device_ms)

    @property
    def offset_ns(self) -> int:
        return min(self.samples) - self.period_ns

    def to_host_ns(self, device_ms: int) -> int:
        return device_ms * 1_000_000 + self.offset_ns


Count = Callable[[str, int], None]


class Link(enum.Enum):
    WAITING = "waiting"  # the device cannot be opened
    STREAMING = "streaming"
    RECONNECTING = "reconnecting"  # the link was lost; waiting before the next attempt


@dataclass
class IngestPolicy:
    """When the ingest gives up on a link, and how long it waits before the next attempt.
    Pure: `now` (monotonic s) and the random draw `u` are passed in."""

    max_consecutive_errors: int
    stall_timeout_s: float
    backoff: Backoff
    state: Link = Link.WAITING
    errors: int = 0  # bad scans in a row
    last_ok: float = -math.inf
    links: int = 0  # transports opened
    scans_this_link: int = 0

    def open_failed(self, u: float) -> tuple[float, bool]:
        """(delay before the next attempt, report it: the first failure of an outage)."""
        report = self.backoff.attempt == 0
        self.state = Link.WAITING
        return self.backoff.next_s(u), report

    def opened(self) -> bool:
        """A transport is open; True when it replaces a lost one (a reconnect)."""
        self.links += 1
        self.errors, self.scans_this_link = 0, 0
        return self.links > 1

    def streaming(self, now: float) -> None:
        """The handshake worked: the stall clock starts now."""
        self.state, self.last_ok = Link.STREAMING, now

    def scan_ok(self, now: float) -> None:
        self.errors, self.last_ok = 0, now
        self.scans_this_link += 1

    def scan_bad(self) -> tuple[bool, bool]:
        """(report it: the 1st, 10th, 100th in a row or the last, give up on the link)."""
        self.errors += 1
        give_up = self.errors >= self.max_consecutive_errors
        return self.errors in (1, 10, 100) or give_up, give_up

    def stalled(self, now: float) -> bool:
        return now - self.last_ok > self.stall_timeout_s

    def lost(self, u: float) -> float:
        """The link is gone: the delay before reopening (quick again if it streamed)."""
        if self.scans_this_link:
            self.backoff.reset()
        self.state = Link.RECONNECTING
        return self.backoff.next_s(u)


class ScanDecoder:
    """Checked scan blocks to LaserScan messages (metres, NaN for error codes, host stamps)."""

    def __init__(self, params: LaserParams, req: scip.ScanRequest, frame_id: str,
                 count: Count, sync_window: int = 100) -> None:
        self.p, self.req, self.frame_id, self.count = params, req, frame_id, count
        self.prefix = req.echo()[:13]  # echo up to the remaining-count field
        self.unwrap = Unwrapper()
        period = params.period_ms * (req.interval + 1)
        self.period_ms = period
        self.sync = ClockSync(sync_window, int(params.period_ms * 1e6))
        self.seq = 0
        self.n = req.size
        inc = 2 * math.pi / params.ares
        # A cluster's angle is the middle of its steps.
        self.angle_min = (req.start + (req.cluster - 1) / 2 - params.afrt) * inc
        self.angle_inc = inc * req.cluster
        # The device stamps the start of its turn (step 0) and takes step k at k/ARES of the
        # period: the first beam published comes that much later, then one per cluster.
        step_ns = params.period_ms * 1e6 / params.ares
        self.first_beam_ns = round((req.start + (req.cluster - 1) / 2) * step_ns)
        self.time_increment_s = step_ns * req.cluster * 1e-9

    def ranges(self, values: npt.NDArray[np.int64]) -> npt.NDArray[np.float64]:
        """A scan's values (mm, or error codes below the device's minimum) in metres, NaN for
        error codes and values out of the device's range."""
        return np.where((values < self.p.dmin_mm) | (values > self.p.dmax_mm), np.nan,
                        values * 1e-3)

    def decode(self, block: bytes, host_rx_ns: int) -> LaserScan:
        scan = scip.parse_scan(block, self.prefix, self.req.nchars)
        if scan.values.size != self.n:
            raise scip.FormatError(f"scan has {scan.values.size} values, want {self.n}")
        dev_ms, delta = self.unwrap.update(scan.timestamp_ms)
        if delta < 0 or delta > 60_000:  # device reset or a corrupt stamp: start over
            self.count("clock_jumps", 1)
            self.sync.reset()
        elif self.seq:
            lost = round(delta / self.period_ms) - 1
            if lost > 0:
                self.count("dropped_scans", lost)
        ranges = self.ranges(scan.values)
        self.seq += 1
        return LaserScan(
            stamp_ns=self.sync.update(dev_ms, host_rx_ns) + self.first_beam_ns,
            frame_id=self.frame_id,
            angle_min_rad=self.angle_min,
            angle_increment_rad=self.angle_inc,
            range_min_m=self.p.dmin_mm * 1e-3,
            range_max_m=self.p.dmax_mm * 1e-3,
            ranges_m=ranges.tolist(),
            scan_seq=self.seq,
            device_time_ms=dev_ms,
            time_increment_s=self.time_increment_s,
        )


class LidarClient:
    """One connection's SCIP session: handshake (SCIP2.0, QT, PP, MD) then scan blocks."""

    def __init__(self, transport: Transport, count: Count, mono: Callable[[], float],
                 reply_timeout_s: float = 1.0) -> None:
        self.t, self.count, self.mono = transport, count, mono
        self.reader = scip.ReplyReader()
        self.reply_timeout_s = reply_timeout_s
        self._pending: list[bytes] = []

    def _blocks(self, timeout_s: float) -> list[bytes]:
        if self._pending:
            out, self._pending = self._pending, []
            return out
        data = self.t.read(timeout_s)
        before = self.reader.discarded
        out = self.reader.feed(data) if data else []
        if self.reader.discarded != before:
            self.count("garbage_bytes", self.reader.discarded - before)
        return out

    def request(self, command: str, params: str = "", *ok: str) -> scip.Reply:
        """Send a request and wait for its reply, skipping stale blocks (e.g. scans still
        streaming from before we connected)."""
        line = scip.encode_request(command, params)
        echo = line[:-1]
        self.t.write(line)
        deadline = self.mono() + self.reply_timeout_s
        while (left := deadline - self.mono()) > 0:
            for i, block in enumerate(blks := self._blocks(left)):
                try:
                    reply = scip.parse_reply(block, echo)
                except scip.ScipError:
                    self.count("stale_blocks", 1)
                    continue
                self._pending = blks[i + 1:]
                if reply.skipped:
                    self.count("garbage_bytes", reply.skipped)
                scip.expect_status(reply, command, *(ok or ("00",)))
                return reply
        raise LidarTimeout(f"no reply to {echo.decode()} within {self.reply_timeout_s} s")

    def start(self, start: int | None, end: int | None, cluster: int, interval: int,
              command: str = "MD") -> tuple[LaserParams, scip.ScanRequest]:
        self.request("SCIP2.0", "", "0", "0E", "00")  # "0": switched from 1.1; "0E": already 2.0
        self.request("QT")
        params = LaserParams.from_pp(scip.parse_info(self.request("PP")))
        s = params.amin if start is None else start
        e = params.amax if end is None else end
        req = scip.ScanRequest(command, s, e, cluster, interval, 0)
        self.request(command, scip.md_params(s, e, cluster, interval, 0))
        return params, req

    def scan_blocks(self, timeout_s: float) -> list[bytes]:
        return self._blocks(timeout_s)
