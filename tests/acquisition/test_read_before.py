"""Sessions recorded before the stream info carried a typed range and LSB (issue 47, item 7) read as
they did: the layout-1 session and a current-layout one recorded with the code before the change
(``data/session_layout2_before.mcap``: the range under two keys, no LSB, 634 clipped samples) give
the clipped flags, clip level, gaps and cycle features that code read from them
(``data/read_before.json``, see data/README.md). The one difference: ``fs`` is now the rate the blocks
recorded (10 kHz exactly) where it was 1/median of the sample steps (within 1e-12 of it), which moves
the features by rounding only."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from wearbench.acquisition.drivers import ACCELERATION, ENCODER
from wearbench.acquisition.layout import clip_level
from wearbench.acquisition.session_file import read_session
from wearbench.testing import recorded_blocks
from wearbench.validation.measurement.features import FeatureSpec, cycle_features
from wearbench.validation.measurement.session import load_session

pytestmark = pytest.mark.no_kernels

DATA = Path(__file__).with_name("data")
FILES = {"layout1": DATA / "session_layout1.mcap", "layout2": DATA / "session_layout2_before.mcap"}
BEFORE = json.loads((DATA / "read_before.json").read_text())


@pytest.mark.parametrize("name", sorted(FILES))
def test_a_session_recorded_before_reads_as_before(name):
    before, path = BEFORE[name], FILES[name]
    r = read_session(path)
    assert len(r.acceleration) == before["samples"]
    assert int(r.acceleration["clipped"].sum()) == before["clipped_column"]
    calibration = r.metadata["calibration"]
    acc = r.streams[ACCELERATION]  # the range as recorded then, typed; no LSB was recorded
    assert acc.range == float(calibration["acceleration.range"]) == float(calibration["accelerometer.range"])
    assert acc.lsb is None and r.clip_level == clip_level(acc.range, None)
    assert (acc.sample_rate, r.streams[ENCODER].sample_rate) == (10000.0, 1000.0)
    s = load_session(path)
    assert s.clip_level == before["clip_level"] and s.gaps == before["gaps"]
    assert s.fs == 10000.0 and s.fs == pytest.approx(before["fs"], rel=1e-12)
    # the features as read then: the test bed's spec at the encoder's angle (a session's default now follows its
    # crank speed, and reads each sample at the angle its stated chain delay puts it)
    f = cycle_features(*s.samples, FeatureSpec(), clipped=s.clipped, fs=s.fs)
    assert f.cycles == before["cycles"]
    assert f.clipped.tolist() == before["features_clipped"]
    np.testing.assert_allclose(f.values, np.array(before["features"]), rtol=1e-9, atol=1e-8)


def test_the_old_recorders_count_is_the_readers():
    """The per-block counts the recorder before the change wrote are what the reader flags now."""
    path = FILES["layout2"]
    blocks = recorded_blocks(path)[ACCELERATION]
    r = read_session(path)
    per_block = r.acceleration.groupby("sequence")["clipped"].sum()
    assert {int(k): int(v) for k, v in per_block.items()} == {k: b.clipped for k, b in blocks.items()}
    assert int(r.metadata["result"]["acceleration.clipped_samples"]) == int(per_block.sum()) == 634
