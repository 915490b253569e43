"""Build helpers for the Arduino firmware tests: the protocol C file as a ctypes library."""

from __future__ import annotations

import ctypes
import shutil
import subprocess
from pathlib import Path

import pytest

FIRMWARE_DIR = Path(__file__).resolve().parent.parent / "firmware" / "autochair_arduino"
MAX_FRAME = 64


class Telemetry(ctypes.Structure):
    _fields_ = [("seq", ctypes.c_uint16), ("t_us", ctypes.c_uint32), ("left", ctypes.c_uint32),
                ("right", ctypes.c_uint32), ("status", ctypes.c_uint8)]


class Command(ctypes.Structure):
    _fields_ = [("seq", ctypes.c_uint16), ("ack_seq", ctypes.c_uint16),
                ("longitudinal_mv", ctypes.c_uint16), ("angular_mv", ctypes.c_uint16),
                ("flags", ctypes.c_uint8)]


class Frame(ctypes.Structure):
    _fields_ = [("type", ctypes.c_uint8), ("tel", Telemetry), ("cmd", Command)]


class RxStats(ctypes.Structure):
    _fields_ = [(n, ctypes.c_uint32) for n in ("frames", "bad_crc", "bad_cobs", "bad_length",
                                               "unknown_type", "oversize", "garbage_bytes")]


class Rx(ctypes.Structure):
    _fields_ = [("buf", ctypes.c_uint8 * MAX_FRAME), ("len", ctypes.c_uint8), ("stats", RxStats)]


class FwCounters(ctypes.Structure):
    _fields_ = [(n, ctypes.c_uint32) for n in ("host_frames", "host_bad_frames", "host_timeouts",
                                               "rejected_commands", "telemetry_frames")]


class Fw(ctypes.Structure):
    _fields_ = [("rx", Rx), ("counters", FwCounters), ("longitudinal_mv", ctypes.c_uint16),
                ("angular_mv", ctypes.c_uint16), ("status", ctypes.c_uint8),
                ("booting", ctypes.c_uint8), ("have_host", ctypes.c_uint8),
                ("timed_out", ctypes.c_uint8), ("seq_started", ctypes.c_uint8),
                ("seq", ctypes.c_uint16), ("last_ack_seq", ctypes.c_uint16),
                ("last_host_us", ctypes.c_uint32)]


def build_protocol_lib(out_dir: Path) -> ctypes.CDLL:
    """Compile ac_protocol.c with the host compiler (warnings are errors) and load it."""
    cc = shutil.which("gcc") or shutil.which("cc")
    if cc is None:
        pytest.skip("no host C compiler (gcc/cc) to build firmware/autochair_arduino/ac_protocol.c")
    lib_path = out_dir / "libac_protocol.so"
    subprocess.run([cc, "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-shared", "-fPIC",
                    "-o", str(lib_path), str(FIRMWARE_DIR / "ac_protocol.c")], check=True)
    lib = ctypes.CDLL(str(lib_path))
    u8p = ctypes.POINTER(ctypes.c_uint8)
    sigs: dict[str, tuple[object, list[object]]] = {
        "ac_crc16": (ctypes.c_uint16, [u8p, ctypes.c_uint8]),
        "ac_cobs_encode": (ctypes.c_uint8, [u8p, ctypes.c_uint8, u8p]),
        "ac_cobs_decode": (ctypes.c_int16, [u8p, ctypes.c_uint8, u8p]),
        "ac_pack_telemetry": (ctypes.c_uint8, [ctypes.POINTER(Telemetry), u8p]),
        "ac_pack_command": (ctypes.c_uint8, [ctypes.POINTER(Command), u8p]),
        "ac_rx_init": (None, [ctypes.POINTER(Rx)]),
        "ac_rx_byte": (ctypes.c_uint8, [ctypes.POINTER(Rx), ctypes.c_uint8,
                                        ctypes.POINTER(Frame)]),
        "ac_fw_init": (None, [ctypes.POINTER(Fw), ctypes.c_uint16]),
        "ac_fw_rx_byte": (None, [ctypes.POINTER(Fw), ctypes.c_uint8, ctypes.c_uint32]),
        "ac_fw_watch": (None, [ctypes.POINTER(Fw), ctypes.c_uint32]),
        "ac_fw_tick": (ctypes.c_uint8, [ctypes.POINTER(Fw), ctypes.c_uint32, ctypes.c_uint32,
                                        ctypes.c_uint32, ctypes.c_uint8, u8p]),
    }
    for name, (restype, argtypes) in sigs.items():
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = restype, argtypes
    return lib


def buf(data: bytes = b"", size: int = 256) -> ctypes.Array[ctypes.c_uint8]:
    return (ctypes.c_uint8 * max(size, len(data)))(*data)


AVR_PACKAGES = ["gcc-avr", "avr-libc", "simavr", "libsimavr-dev", "libelf-dev", "pkg-config",
                "make"]


def _have_avr_tools() -> bool:
    return all(shutil.which(t) for t in ("avr-gcc", "avr-objcopy", "make", "pkg-config")) and \
        Path("/usr/include/simavr/sim_avr.h").exists()


def ensure_avr_toolchain() -> None:
    """avr-gcc, avr-libc and libsimavr (`./dev test` installs them from Debian), else skip."""
    if not _have_avr_tools():
        pytest.skip("avr-gcc/simavr missing: run ./dev test as root, or "
                    f"apt-get install -y {' '.join(AVR_PACKAGES)}")


def build_firmware(build_dir: Path) -> tuple[Path, Path]:
    """`make` the firmware ELF and the simavr harness into build_dir; return both paths."""
    ensure_avr_toolchain()
    r = subprocess.run(["make", "-s", "-C", str(FIRMWARE_DIR), f"BUILD={build_dir}", "all",
                        "harness"], capture_output=True, text=True, timeout=300)
    if r.returncode != 0:
        pytest.fail(f"firmware build failed:\n{r.stdout[-2000:]}\n{r.stderr[-2000:]}")
    return build_dir / "autochair_arduino.elf", build_dir / "simavr_harness"
