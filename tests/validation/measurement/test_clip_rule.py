"""One clip rule (issues 25 and 28). A positive full-scale 16-bit sample (+32767 counts, one LSB below
the range) was clipped for the recorder and not for the identification, which also took the range
from the bench file instead of the session's recorded calibration. The measured session now owns
the clip level (the recorder's rule on the recorded calibration) and the features take it."""

from __future__ import annotations

import math
import re

import numpy as np
import pandas as pd
from wearbench.acquisition.backends import open_rig
from wearbench.acquisition.layout import clip_level, count_clipped
from wearbench.acquisition.recorder import Recorder
from wearbench.acquisition.session import SessionPlan
from wearbench.acquisition.session_file import read_session
from wearbench.bench.load import load_bench, parse_bench, shipped_bench
from wearbench.validation.measurement.session import MeasuredSession, load_session

RANGE = 196.133  # m/s^2: 20 g recorded, while the bench file says 500 g


def _session(peak_counts: int) -> MeasuredSession:
    fs, rev = 4000.0, 0.25  # 4 revolutions at 4 Hz
    t = np.arange(0, 4.2, 1 / fs)
    angle = 2 * np.pi * t / rev
    counts = np.round(20000 * np.sin(3 * angle)).astype(int)
    counts[counts.size // 2] = peak_counts  # one saturated sample in the middle
    acc = counts * (RANGE / 32768)
    calibration = {"acceleration.range": f"{RANGE}", "acceleration.lsb": f"{RANGE / 32768}"}
    return MeasuredSession("s", pd.DataFrame({"time": t, "acc": acc}), pd.DataFrame({"time": t, "angle": angle}),
                           bench=load_bench(shipped_bench("ninebar-testbed")), metadata={"calibration": calibration})


def test_a_full_scale_sample_is_clipped_for_recorder_and_identification_alike():
    s = _session(32767)
    assert s.clip_level == clip_level(RANGE, RANGE / 32768)  # the recorded range, not the bench's
    full = np.array([32767 * RANGE / 32768])
    assert count_clipped(full, clip_level(RANGE, RANGE / 32768)) == 1  # the recorder's count
    assert s.features().clipped.sum() == 1  # the identification's, the same sample
    assert _session(32766).features().clipped.sum() == 0  # one count lower is a measurement
    negative = _session(-32768)
    assert negative.features().clipped.sum() == 1


def test_a_session_without_a_recorded_range_has_no_clip_level():
    """The bench file's range is not the recorded one: without a recorded calibration nothing is
    counted as clipped (the recorder counted nothing either)."""
    s = _session(32767)
    s = MeasuredSession("s", s.acceleration, s.encoder, bench=s.bench)
    assert s.clip_level is None
    assert s.features().clipped.sum() == 0


def test_a_recorded_session_counts_the_recorders_clipped_samples(wearbench_bench, tmp_path):
    """Recorded from the emulator with a 10 g range on a signal that exceeds it: the positive
    full-scale samples the device sends (+32767 counts) are among the recorder's clipped ones, and
    the identification's features count exactly the recorder's flags inside their complete cycles."""
    small = parse_bench(re.sub(r'\nrange = "[^"]*"', '\nrange = "10 g"', wearbench_bench.source), wearbench_bench.path)
    full_scale = small.sensor("accelerometer").range
    rig = open_rig(small, "sim", {"speedup": math.inf, "config": {"signal": "harmonic", "cache": False}})
    out = tmp_path / "clipped.mcap"
    try:
        result = Recorder(rig, small, SessionPlan(speed=62.0, cycles=4), out).run()
    finally:
        rig.close()
    assert result.completed, result.reason
    flags = read_session(out).acceleration["clipped"].to_numpy(bool)
    assert flags.sum() == result.clipped > 0  # the reader flags what the recorder counted
    s = load_session(out)
    acc = s.acceleration["acc"].to_numpy(float)
    positive = np.float32(32767 * full_scale / 32768)
    assert np.any(acc == positive) and np.all(flags[acc == positive])  # +32767 counts: clipped
    assert s.clip_level == clip_level(full_scale, full_scale / 32768)
    features = s.features()
    inside = (s.turns.cycle >= s.turns.first) & (s.turns.cycle <= s.turns.last)
    assert features.clipped.sum() == flags[inside].sum() > 0
    per_cycle = np.bincount(s.turns.cycle[inside & flags] - s.turns.first, minlength=features.cycles)
    np.testing.assert_array_equal(features.clipped, per_cycle)
