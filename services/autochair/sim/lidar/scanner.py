"""Simulated Hokuyo URG-04LX, pure: the SCIP state machine and the scan it sees.

`UrgDevice.handle(line, now_s)` answers one request line; `UrgDevice.poll(now_s)` returns the
MD/MS scan blocks due by `now_s` (seconds since the device booted). No I/O or clock here: the
node (`sim_node`) owns the pty/TCP endpoints and passes time in. Like the real sensor it boots in
SCIP 1.1 mode and only answers `SCIP2.0` (status `0`) until switched.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from autochair.protocol import scip

from ..world import World, raycast

ERR_NO_RETURN = 1  # device error code for "nothing within DMAX" (any value < DMIN is an error)
ERR_TOO_CLOSE = 2


@dataclass(frozen=True)
class UrgParams:
    """PP values of a URG-04LX (spec), plus the scan rate (SCAN rpm = 60 × scans/s)."""

    model: str = "URG-04LX(Hokuyo Automatic Co.,Ltd.)"
    dmin_mm: int = 20
    dmax_mm: int = 5600
    ares: int = 1024
    amin: int = 44
    amax: int = 725
    afrt: int = 384
    scan_rate_hz: float = 10.0

    @property
    def scan_rpm(self) -> int:
        return round(self.scan_rate_hz * 60)

    def pp(self) -> dict[str, str]:
        return {"MODL": self.model, "DMIN": str(self.dmin_mm), "DMAX": str(self.dmax_mm),
                "ARES": str(self.ares), "AMIN": str(self.amin), "AMAX": str(self.amax),
                "AFRT": str(self.afrt), "SCAN": str(self.scan_rpm)}

    def step_angles(self) -> npt.NDArray[np.float64]:
        """Angle in the laser frame of every step AMIN..AMAX."""
        return scip.angles_rad(np.arange(self.amin, self.amax + 1), self.afrt, self.ares)


# Serial number etc. as a URG-04LX reports them (VV/II); the values are plausible, not a unit's.
VV = {"VEND": "Hokuyo Automatic Co.,Ltd.", "PROD": "SOKUIKI Sensor URG-04LX",
      "FIRM": "3.4.03(17/Dec./2012)", "PROT": "SCIP 2.0", "SERI": "H1234567"}

ScanFn = Callable[[float], npt.NDArray[np.int64]]  # now_s -> raw values for steps AMIN..AMAX


class UrgDevice:
    def __init__(self, params: UrgParams, scan_fn: ScanFn, clock_start_ms: int = 0) -> None:
        self.p = params
        self.scan_fn = scan_fn
        self.clock_start_ms = clock_start_ms
        self.scip2 = False
        self.laser_on = False
        self.time_mode = False
        self.stream: scip.ScanRequest | None = None
        self._next_scan_s = 0.0
        self._scan_index = 0  # scans since the stream started (for interval skipping)
        self._remaining = 0
        self.scans_sent = 0
        # Scans the device owed but never sent because its caller (this simulator's process)
        # stalled past their slots: a gap in the device clock that the ingest counts as
        # dropped_scans, though nothing was lost on the link.
        self.skipped_scans = 0

    @property
    def period_s(self) -> float:
        return 1.0 / self.p.scan_rate_hz

    def clock_ms(self, now_s: float) -> int:
        return (self.clock_start_ms + round(now_s * 1000.0)) & 0xFFFFFF

    # --- requests ----------------------------------------------------------------------------
    def handle(self, line: bytes, now_s: float) -> bytes:
        line = line.rstrip(b"\r")
        if not self.scip2:
            if line == b"SCIP2.0":
                self.scip2 = True
                return b"SCIP2.0\n0\n\n"
            return line + b"\nE\n\n"  # what a SCIP 1.1 device says to a 2.0 command
        text = line.decode("ascii", "replace")
        body = text.partition(";")[0]
        cmd = body[:2]

        def ok(status: str = "00", lines: tuple[bytes, ...] = ()) -> bytes:
            return scip.encode_reply(line, status, lines)

        if len(line) > 64:
            return ok("0C")
        if body == "SCIP2.0":
            return ok("0E")  # already in SCIP 2.0: undefined command
        if body == "VV":
            return ok("00", tuple(scip.encode_info(VV)))
        if body == "PP":
            return ok("00", tuple(scip.encode_info(self.p.pp())))
        if body == "II":
            ii = {"MODL": "URG-04LX", "LASR": "ON" if self.laser_on else "OFF",
                  "SCSP": f"Initial({self.p.scan_rpm}[rpm])", "MESM": "Measuring by Normal Mode",
                  "SBPS": "USB only", "TIME": scip.encode_value(self.clock_ms(now_s), 4).decode(),
                  "STAT": "Stable 000 no error."}
            return ok("00", tuple(scip.encode_info(ii)))
        if body == "BM":
            if self.laser_on:
                return ok("02")
            self.laser_on = True
            return ok()
        if body in ("QT", "RS"):
            self.laser_on, self.stream, self.time_mode = False, None, False
            return ok()
        if cmd == "TM" and body in ("TM0", "TM1", "TM2"):
            if body == "TM0":
                self.time_mode, self.stream = True, None
                return ok()
            if not self.time_mode:
                return ok("01")
            if body == "TM2":
                self.time_mode = False
                return ok()
            ts = scip.with_sum(scip.encode_value(self.clock_ms(now_s), 4))
            return ok("00", (ts,))
        if cmd in ("MD", "MS"):
            return self._start_stream(line, body, now_s)
        return ok("0E")

    def _start_stream(self, line: bytes, body: str, now_s: float) -> bytes:
        fields = [(2, 6, "01"), (6, 10, "02"), (10, 12, "03"), (12, 13, "06"), (13, 15, "07")]
        if len(body) != 15:
            return scip.encode_reply(line, "0C")
        for a, b, code in fields:
            if not body[a:b].isdigit():
                return scip.encode_reply(line, code)
        req = scip.ScanRequest.parse(line)
        if req.end > self.p.amax:
            return scip.encode_reply(line, "04")
        if req.end < req.start:
            return scip.encode_reply(line, "05")
        if self.time_mode:
            return scip.encode_reply(line, "0L")  # not allowed in time-adjust mode
        self.laser_on, self.stream = True, req
        self._scan_index, self._remaining = 0, req.count
        self._next_scan_s = now_s + self.period_s
        return scip.encode_reply(line, "00")

    # --- streaming ---------------------------------------------------------------------------
    def next_due_s(self) -> float | None:
        return self._next_scan_s if self.stream is not None else None

    def poll(self, now_s: float) -> list[bytes]:
        """Scan blocks due by `now_s`; missed slots (a stalled caller) are skipped, not bunched."""
        out: list[bytes] = []
        req = self.stream
        if req is None or now_s < self._next_scan_s:
            return out
        t_scan = self._next_scan_s
        missed = int((now_s - t_scan) / self.period_s)
        self._next_scan_s = t_scan + (missed + 1) * self.period_s
        every = req.interval + 1  # scan j (from 1) is sent when (j − 1) % every == 0
        first = self._scan_index  # = (first missed j) − 1
        self.skipped_scans += (first + missed - 1) // every - (first - 1) // every
        self._scan_index += missed + 1
        if (self._scan_index - 1) % (req.interval + 1):
            return out
        if req.count:
            self._remaining -= 1
            if self._remaining <= 0:
                self.stream = None
        slot = t_scan + missed * self.period_s  # when this scan finished
        out.append(self.scan_block(req, max(self._remaining, 0) if req.count else 0, slot))
        return out

    def scan_block(self, req: scip.ScanRequest, remaining: int, end_s: float) -> bytes:
        raw = self.scan_fn(end_s)  # steps AMIN..AMAX
        steps = np.arange(req.start, req.end + 1)
        vals = np.full(steps.size, ERR_NO_RETURN, dtype=np.int64)
        inside = (steps >= self.p.amin) & (steps <= self.p.amax)
        vals[inside] = raw[steps[inside] - self.p.amin]
        if req.cluster > 1:  # a cluster reports the minimum of its steps (spec)
            pad = (-vals.size) % req.cluster
            grid = np.concatenate([vals, np.full(pad, vals[-1])]).reshape(-1, req.cluster)
            vals = grid.min(axis=1)
        if req.nchars == 2:
            vals = np.minimum(vals, 4095)
        self.scans_sent += 1
        # The timestamp is when the scan started, one period before it is sent.
        stamp = self.clock_ms(max(end_s - self.period_s, 0.0))
        return scip.encode_scan(req, remaining, stamp, vals)


def beam_rays(params: UrgParams, pose: tuple[float, float, float],
              mount: tuple[float, float, float], twist: tuple[float, float] = (0.0, 0.0)
              ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64],
                         npt.NDArray[np.float64]]:
    """Each beam's origin (x, y) and bearing in the world for steps AMIN..AMAX, the chair at
    `pose` at the end of the sweep moving at `twist` (see ray_scan)."""
    x, y, yaw = pose
    mx, my, myaw = mount
    steps = np.arange(params.amin, params.amax + 1)
    v, omega = twist
    age = (1.0 - steps / params.ares) / params.scan_rate_hz  # s before the end of the sweep
    th = yaw - omega * age
    if abs(omega) > 1e-9:
        cx = x - v / omega * (math.sin(yaw) - np.sin(th))
        cy = y + v / omega * (math.cos(yaw) - np.cos(th))
    else:
        cx, cy = x - v * age * math.cos(yaw), y - v * age * math.sin(yaw)
    return (cx + mx * np.cos(th) - my * np.sin(th), cy + mx * np.sin(th) + my * np.cos(th),
            params.step_angles() + th + myaw)


def ray_scan(world: World, params: UrgParams, pose: tuple[float, float, float],
             mount: tuple[float, float, float], noise_std_m: float,
             rng: np.random.Generator,
             twist: tuple[float, float] = (0.0, 0.0)) -> npt.NDArray[np.int64]:
    """Raw URG values (mm or error codes) for steps AMIN..AMAX seen from chair `pose` (x, y,
    yaw in world) with the laser at `mount` (x, y, yaw in the chair frame).

    `pose` is the chair's at the end of the sweep, moving at `twist` (v m/s, ω rad/s): the
    laser turns once a period and takes step k at k/ARES of it, so each beam is cast from
    where the chair was then (constant twist over the sweep), as a real laser on a moving
    chair skews its scan."""
    lx, ly, angles = beam_rays(params, pose, mount, twist)
    r = raycast(world, lx, ly, angles, params.dmax_mm / 1000.0)
    if noise_std_m > 0:
        r = r + rng.normal(0.0, noise_std_m, r.shape)
    mm = np.rint(np.where(np.isfinite(r), r, 0.0) * 1000.0).astype(np.int64)
    return np.where(~np.isfinite(r) | (mm > params.dmax_mm), ERR_NO_RETURN,
                    np.where(mm < params.dmin_mm, ERR_TOO_CLOSE, mm))
