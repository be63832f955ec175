"""One clip rule, applied once where samples enter (issues 25, 28 and 47). A positive full-scale 16-bit
sample (+32767 counts, one LSB below the range) was clipped for the recorder and not for the
identification, which also took the range from the bench file instead of the session's; later the
range travelled as text through two keys and the rule ran three times. Now the stream info carries
the range and LSB typed, the session records them once, the reader flags each sample by the rule on
them, and the features count the reader's ``clipped`` column: the recorder's count and the
analysis's are the same number by construction."""

from __future__ import annotations

import math
import re
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest
from wearbench.acquisition.backends import open_rig
from wearbench.acquisition.drivers import ACCELERATION
from wearbench.acquisition.layout import clip_level, count_clipped
from wearbench.acquisition.recorder import Recorder
from wearbench.acquisition.session import SessionPlan
from wearbench.acquisition.session_file import read_session
from wearbench.bench.load import parse_bench
from wearbench.hardware.protocol.messages import counts_to_m_s2
from wearbench.testing import recorded_blocks
from wearbench.validation.measurement.cycles import crank_turns
from wearbench.validation.measurement.scaling import resolve_analysis
from wearbench.validation.measurement.session import MeasuredSession, load_session

pytestmark = pytest.mark.no_kernels

G = 9.80665
RANGE = 20 * G  # m/s^2: what the device runs at in the sessions below, while the bench file says 500 g


def test_the_rule_at_full_scale():
    """+32767 counts (one LSB below the range) and -32768 are clipped, +32766 is a measurement."""
    level = clip_level(RANGE, RANGE / 32768)
    assert level == clip_level(RANGE)  # no LSB stated: the protocols' range/32768
    counts = np.array([32767, 32766, -32768, -32767], dtype=np.float64)
    flags = [count_clipped(np.float32(c * RANGE / 32768)[None], level) for c in counts]
    assert flags == [1, 0, 1, 1]
    assert clip_level(None) == math.inf == clip_level(0.0)


def _frames(peak_counts: int | None = None) -> tuple[pd.DataFrame, pd.DataFrame]:
    fs, rev = 4000.0, 0.25  # 4 revolutions at 4 Hz
    t = np.arange(0, 4.2, 1 / fs)
    angle = 2 * np.pi * t / rev
    counts = np.round(20000 * np.sin(3 * angle)).astype(int)
    if peak_counts is not None:
        counts[counts.size // 2] = peak_counts
    return pd.DataFrame({"time": t, "acc": counts * (RANGE / 32768)}), pd.DataFrame({"time": t, "angle": angle})


def test_a_session_built_from_frames_counts_its_clipped_column():
    """The features count the flags the acceleration frame carries, per cycle; a frame without a
    ``clipped`` column (no reader flagged it) has no clip level and counts none, whatever its
    metadata says."""
    acc, enc = _frames(32767)
    s = MeasuredSession("s", acc, enc, metadata={"calibration": {"acceleration.range": repr(RANGE)}})
    assert s.clip_level is None and not s.clipped.any()
    assert s.features().clipped.sum() == 0
    flagged = acc.assign(clipped=np.abs(acc["acc"]) >= clip_level(RANGE))
    s = MeasuredSession("s", flagged, enc, clip_level=clip_level(RANGE))
    assert s.clipped.sum() == 1 and s.features().clipped.sum() == 1


def _record(bench, tmp_path, name: str, *, device_range: float, lsb: float | None = None):
    """A 4-cycle sim session of ``bench`` whose device runs at ``device_range`` (a DAQ that picks its own
    hardware range, whatever the bench file asks) and whose stream states ``lsb``; its result and file."""
    rig = open_rig(bench, "sim", {"speedup": math.inf, "config": {"signal": "harmonic", "cache": False}})
    source = rig.sources[0]
    configure, describe = source.configure, source.describe
    source.configure = lambda _range, rate: configure(device_range, rate)
    source.describe = lambda: tuple(replace(i, lsb=lsb) if i.name == ACCELERATION else i for i in describe())
    out = tmp_path / f"{name}.mcap"
    try:
        result = Recorder(rig, bench, SessionPlan(speed=62.0, cycles=4), out).run()
    finally:
        rig.close()
    assert result.completed, result.reason
    return result, out


def _same_count_everywhere(result, out) -> np.ndarray:
    """The recorder's count (its result, the result record, each block's) is the reader's column and,
    inside complete cycles, the features' per-cycle counts; the reader's flags."""
    blocks = recorded_blocks(out)[ACCELERATION]
    r = read_session(out)
    flags = r.acceleration["clipped"].to_numpy(bool)
    assert result.clipped == sum(b.clipped for b in blocks.values()) == flags.sum() > 0
    assert r.metadata["result"]["acceleration.clipped_samples"] == str(result.clipped)
    per_block = r.acceleration.groupby("sequence")["clipped"].sum()
    assert {int(k): int(v) for k, v in per_block.items()} == {k: b.clipped for k, b in blocks.items()}
    s = load_session(out)
    np.testing.assert_array_equal(s.clipped, flags)
    assert s.clip_level == r.clip_level
    features = s.features()
    # the features bin each sample at the crank angle it was measured at (the chain's stated delay)
    turns = crank_turns(s.feature_angle(resolve_analysis(s.bench, s.commanded_speed).features))
    inside = (turns.cycle >= turns.first) & (turns.cycle <= turns.last)
    per_cycle = np.bincount(turns.cycle[inside & flags] - turns.first, minlength=features.cycles)
    np.testing.assert_array_equal(features.clipped, per_cycle)
    assert features.clipped.sum() == flags[inside].sum() > 0
    return flags


def test_the_recorded_range_not_the_benchs(wearbench_bench, tmp_path):
    """The bench file says 500 g; the device runs at 20 g and its stream says so. The session records
    20 g once (no second key), the reader gives it back typed and flags by it, and the recorder, the
    reader and the features count the same samples, among them every full-scale one."""
    assert wearbench_bench.sensor("accelerometer").range == pytest.approx(500 * G)
    result, out = _record(wearbench_bench, tmp_path, "range", device_range=RANGE)
    calibration = read_session(out).metadata["calibration"]
    assert calibration["acceleration.range"] == repr(RANGE)
    assert not {"accelerometer.range", "acceleration.lsb"} & set(calibration)  # one key; no LSB stated
    r = read_session(out)
    acc = r.streams[ACCELERATION]
    assert (acc.range, acc.lsb, acc.unit, acc.sample_rate) == (RANGE, None, "m/s^2", 10000.0)
    assert r.clip_level == clip_level(RANGE)
    flags = _same_count_everywhere(result, out)
    values = r.acceleration["acc"].to_numpy()
    extreme = counts_to_m_s2(np.array([-32768]), RANGE / 32768)[0]  # the negative full-scale code
    assert np.any(values == extreme) and np.all(flags[values == extreme])
    assert not np.any(np.abs(values) >= clip_level(500 * G))  # the bench's range would flag nothing


def test_a_stated_lsb_is_recorded_and_used(wearbench_bench, tmp_path):
    """A stream that states its LSB (a 12-bit converter's: range/2048) has it recorded as
    ``acceleration.lsb`` and the clip level follows it in the recorder and the reader alike: samples
    within one 12-bit step of full scale are clipped, more than at the 16-bit step."""
    lsb = RANGE / 2048
    result, out = _record(wearbench_bench, tmp_path, "lsb", device_range=RANGE, lsb=lsb)
    r = read_session(out)
    assert r.metadata["calibration"]["acceleration.lsb"] == repr(lsb)
    assert r.streams[ACCELERATION].lsb == lsb and r.clip_level == clip_level(RANGE, lsb)
    flags = _same_count_everywhere(result, out)
    values = r.acceleration["acc"].to_numpy()
    assert flags.sum() > np.count_nonzero(np.abs(values) >= clip_level(RANGE))


def test_a_recorded_session_counts_the_recorders_clipped_samples(wearbench_bench, tmp_path):
    """Recorded from the emulator with a 10 g range in the bench file on a signal that exceeds it: the
    positive full-scale samples the device sends (+32767 counts) are among the recorder's clipped
    ones, and the identification's features count exactly the recorder's flags inside their
    complete cycles."""
    small = parse_bench(re.sub(r'\nrange = "[^"]*"', '\nrange = "10 g"', wearbench_bench.source), wearbench_bench.path)
    full_scale = small.sensor("accelerometer").range
    rig = open_rig(small, "sim", {"speedup": math.inf, "config": {"signal": "harmonic", "cache": False}})
    out = tmp_path / "clipped.mcap"
    try:
        result = Recorder(rig, small, SessionPlan(speed=62.0, cycles=4), out).run()
    finally:
        rig.close()
    assert result.completed, result.reason
    flags = _same_count_everywhere(result, out)
    s = load_session(out)
    acc = s.acceleration["acc"].to_numpy(float)
    positive = np.float32(32767 * full_scale / 32768)
    assert np.any(acc == positive) and np.all(flags[acc == positive])  # +32767 counts: clipped
    assert s.clip_level == clip_level(full_scale, full_scale / 32768)
