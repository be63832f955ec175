"""Issue 25, item 9: one clip rule. A positive full-scale 16-bit sample (+32767 counts, one LSB below
the range) was clipped for the recorder and not for the identification, which also took the range
from the bench file instead of the session's recorded calibration."""

from __future__ import annotations

import numpy as np
import pandas as pd
from wearbench.acquisition.layout import clip_level, count_clipped
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.validation.assess import session_clip_level, session_features
from wearbench.validation.measured import MeasuredSession

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
    assert session_clip_level(s) == clip_level(RANGE, RANGE / 32768)  # the recorded range, not the bench's
    full = np.array([32767 * RANGE / 32768])
    assert count_clipped(full, clip_level(RANGE, RANGE / 32768)) == 1  # the recorder's count
    assert session_features(s).clipped.sum() == 1  # the identification's, the same sample
    assert session_features(_session(32766)).clipped.sum() == 0  # one count lower is a measurement
    negative = _session(-32768)
    assert session_features(negative).clipped.sum() == 1
