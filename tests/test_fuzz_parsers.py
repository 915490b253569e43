"""Property tests: the frame decoder and the SCIP parser never crash and count every rejection."""

from __future__ import annotations

import random

from bench.fuzz import arduino_corpus, fuzz_arduino, fuzz_scip, mutate, scip_corpus
from hypothesis import given, settings
from hypothesis import strategies as st

from autochair.protocol import arduino, scip

CORPUS = arduino_corpus(random.Random(0))
SCANS = scip_corpus(random.Random(0))


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=200))
def test_frame_decoder_random_bytes(data: bytes) -> None:
    dec = arduino.FrameDecoder()
    frames = dec.feed(data + b"\x00")
    if not frames and data.strip(b"\x00"):
        assert dec.stats.bad_frames > 0  # rejected, and counted


@settings(max_examples=300, deadline=None)
@given(st.integers(0, len(CORPUS) - 1), st.integers(0, 2**32), st.binary(max_size=20))
def test_frame_decoder_mutations_then_a_valid_frame_resyncs(i: int, seed: int,
                                                           junk: bytes) -> None:
    dec = arduino.FrameDecoder()
    bad = mutate(random.Random(seed), CORPUS[i], CORPUS)
    dec.feed(bad + junk + b"\x00")
    frames = dec.feed(CORPUS[0])  # after any garbage and a delimiter, the next frame decodes
    assert len(frames) == 1 and arduino.encode(frames[0]) == CORPUS[0]


@settings(max_examples=200, deadline=None)
@given(st.integers(0, len(SCANS) - 1), st.integers(0, 2**32))
def test_scip_mutated_scans_raise_only_scip_errors(i: int, seed: int) -> None:
    block, prefix, nchars = SCANS[i]
    data = mutate(random.Random(seed), block, [b for b, _, _ in SCANS])
    for reply in scip.ReplyReader().feed(data + b"\n\n"):
        try:
            scan = scip.parse_scan(reply, prefix, nchars)
        except scip.ScipError:
            continue
        assert scan.values.size == 0 or scan.values.min() >= 0


def test_bench_fuzzers_small_run_finds_no_crash() -> None:
    a = fuzz_arduino(random.Random(3), 3000, 1000)
    s = fuzz_scip(random.Random(3), 3000, 1000)
    assert a["crashes"] == 0 and s["crashes"] == 0
    outcomes = a["outcomes"]
    assert isinstance(outcomes, dict) and outcomes.get("uncounted", 0) == 0
    assert outcomes["accepted_input"] > 0 and outcomes["rejected_input"] > 0
