"""The sample rate is a measured fact read from what was recorded (issue 47, item 7): every block
carries the rate it was taken at, the reader gives the session that rate and the session carries it to
its features, gaps and stream start. A session whose sample times jitter (a device that stamps each
sample with a jittering timer) but whose recorded rate is exact has the recorded rate, where
1/median of its sample steps, as it used to be derived, is not."""

from __future__ import annotations

import numpy as np
import pytest
from wearbench.acquisition.drivers import ACCELERATION, ENCODER, Block, StreamInfo
from wearbench.acquisition.layout import record_stream
from wearbench.acquisition.session_file import read_session
from wearbench.acquisition.session_writer import SessionWriter
from wearbench.validation.measurement.features import FeatureSpec, cycle_features, sample_rate
from wearbench.validation.measurement.session import load_session

pytestmark = pytest.mark.no_kernels

RATE, ENCODER_RATE, CPR, TURNS_PER_S = 10000.0, 1000.0, 4000, 10.0


def _jittered_session(path, jitter: float, seed: int = 0) -> None:
    """0.5 s of a 10 rev/s crank: one acceleration sample per block, stamped ``jitter`` periods
    (uniform, either way) off its true time, every block recording the exact rate; encoder counts
    in blocks of 10 at 1 kHz."""
    rng = np.random.default_rng(seed)
    calibration = {"encoder.counts_per_rev": str(CPR), "encoder.angle_offset": "0.0"}
    record_stream(calibration, StreamInfo(ACCELERATION, "m/s^2", RATE, "float32", source="jittering DAQ",
                                          range=500.0), "test")
    record_stream(calibration, StreamInfo(ENCODER, "counts", ENCODER_RATE, "int32", source="test"), "test")
    w = SessionWriter(path, ballast=False)
    w.start({"session": {"bench": "none", "operator": "test"}, "calibration": calibration}, {})
    n = int(0.5 * RATE)
    t = np.arange(n) / RATE
    acc = (100.0 * np.sin(2 * np.pi * 3 * TURNS_PER_S * t)).astype(np.float32)
    stamps = t + rng.uniform(-jitter, jitter, n) / RATE
    for i in range(n):
        w.write_block(Block(ACCELERATION, i, float(stamps[i]), RATE, acc[i:i + 1], 1.7e9 + stamps[i]))
    te = np.arange(int(0.5 * ENCODER_RATE)) / ENCODER_RATE
    counts = np.round(CPR * TURNS_PER_S * te).astype(np.int32)
    index = counts % CPR < CPR * TURNS_PER_S / ENCODER_RATE
    for k in range(0, te.size, 10):
        w.write_block(Block(ENCODER, k // 10, float(te[k]), ENCODER_RATE, counts[k:k + 10], 1.7e9 + te[k],
                            index[k:k + 10]))
    w.finish()


def test_the_recorded_rate_not_the_steps(tmp_path):
    path = tmp_path / "jitter.mcap"
    _jittered_session(path, jitter=0.2)
    r = read_session(path)
    assert r.sample_rate == r.streams[ACCELERATION].sample_rate == RATE
    assert r.streams[ENCODER].sample_rate == ENCODER_RATE
    assert r.streams[ACCELERATION].source == "jittering DAQ" and r.streams[ACCELERATION].range == 500.0
    s = load_session(path)
    t = s.acceleration["time"].to_numpy()
    assert s.fs == RATE  # exactly: as recorded
    assert abs(sample_rate(t) - RATE) > 1.0  # the steps' median is off by more than 1 Hz
    assert s.gaps == 0  # steps of 0.6..1.4 periods: no dropped samples at the recorded rate
    spec = FeatureSpec()
    f = s.features(spec)
    np.testing.assert_array_equal(f.values, cycle_features(*s.samples, spec, fs=RATE).values)
    assert f.cycles >= 3
    assert not np.allclose(f.values, cycle_features(*s.samples, spec, fs=sample_rate(t)).values, rtol=1e-9)


def test_a_session_from_frames_has_the_rate_of_its_times():
    """Built in Python from frames with no recording behind them, a session takes the rate of its
    sample times; given one, it carries that."""
    import pandas as pd
    from wearbench.validation.measurement.session import MeasuredSession

    t = np.arange(4000) / 4000.0
    frames = (pd.DataFrame({"time": t, "acc": np.sin(2 * np.pi * 12 * t)}),
              pd.DataFrame({"time": t, "angle": 2 * np.pi * 4 * t}))
    assert MeasuredSession("s", *frames).fs == pytest.approx(4000.0, rel=1e-9)
    assert MeasuredSession("s", *frames, fs=4000.0).fs == 4000.0
