"""The tap test against independent truth: the emulator's ``accel_delay`` (and, on a drawn mount the
statement does not name, the delay its chain really adds in the windows' band, from its digital
filters) recovered from recorded tap sessions; a planted shift recovered on a synthetic filtered
impulse; the errors a lab meets; the bench file edit."""

from __future__ import annotations

import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy import signal as sps
from wearbench.acquisition.backends import open_rig
from wearbench.acquisition.recorder import record_session
from wearbench.acquisition.session import SessionPlan
from wearbench.bench.chain_latency import ChainEditError, with_chain_latency
from wearbench.bench.load import BENCH_DIR, load_bench
from wearbench.bench.schema import SensorChainStatement
from wearbench.hardware.emulators.config import emulator_config
from wearbench.hardware.emulators.sensor import SensorChain
from wearbench.validation.measurement import tap_test as tt
from wearbench.validation.measurement.chain_delay import stated_delay, stated_response

pytestmark = pytest.mark.no_kernels

TOLERANCE = 2e-5  # s: the 0.02 ms


def record_taps(bench, path: Path, *, delay: float = 0.0, seed: int = 7, spread: bool = False, taps: int = 6,
                **plan) -> tuple[Path, object]:
    """A tap session of the sim bench whose truth is late by ``delay`` s; (path, emulator config)."""
    table = {**bench.emulator, "truth": {"accel_delay": f"{delay * 1e3!r} ms"}}
    cfg = emulator_config(bench, bench.states[0], seed, table=table, accelerometer={"spread": {}} if spread else None)
    rig = open_rig(bench, "sim", {"speedup": float("inf"), "config": cfg.to_table()})
    result = record_session(rig, bench, SessionPlan(0.0, taps=taps, **plan), path)
    assert result.completed, result.reason
    return path, cfg


def needed_latency(bench, cfg) -> float:
    """Independent truth: the emulator's delay in the windows' band (accel_delay + its digital filters'
    group delay averaged over 1-100 Hz, as it runs them) less what the statement's filters account for."""
    acc = bench.sensor("accelerometer")
    chain = SensorChain(cfg.accelerometer, acc.sample_rate, acc.range, np.random.default_rng(0))
    _, gd = sps.group_delay(sps.sos2tf(chain.sos), w=np.linspace(1.0, 100.0, 64), fs=chain.internal_rate)
    stated = stated_delay(acc.chain)
    return cfg.truth.accel_delay + float(np.mean(gd)) / chain.internal_rate - stated.filter - stated.sensor


@pytest.mark.parametrize("delay", [0.0, 0.25e-3, 0.5e-3, 1e-3])
def test_the_latency_is_the_emulators_accel_delay(wearbench_bench, tmp_path, delay):
    """On the bench's own stated chain the latency is the truth's accel_delay, within 0.02 ms (measured:
    within 2 us; the latch's 1 us step and the digital filters against their analogue statement)."""
    path, cfg = record_taps(wearbench_bench, tmp_path / "taps.mcap", delay=delay)
    result = tt.tap_test(path)
    assert abs(result.latency - delay) < TOLERANCE
    assert abs(result.latency - needed_latency(wearbench_bench, cfg)) < 5e-6
    assert result.interval[0] <= result.latency <= result.interval[1] and result.coverage > 0.9
    assert all(abs(t.latency - delay) < TOLERANCE for t in result.taps)
    assert all(t.snr > 100 and t.match > 0.99 for t in result.taps)
    assert result.line() == f'latency = "{result.latency * 1e3:.3f} ms"'


@pytest.mark.parametrize("seed", [11, 12, 13])
def test_on_a_drawn_mount_the_latency_is_what_the_windows_need(wearbench_bench, tmp_path, seed):
    """A mount mode the statement does not name (SensorSpread, 0.3-3 kHz) delays the windows' band too:
    the tap test's latency carries it, within 0.02 ms of the emulator chain's own delay there."""
    delay = 0.1e-3 * (seed - 10)
    path, cfg = record_taps(wearbench_bench, tmp_path / "taps.mcap", delay=delay, seed=seed, spread=True)
    assert cfg.accelerometer.resonance < 3000.0
    result = tt.tap_test(path)
    assert abs(result.latency - needed_latency(wearbench_bench, cfg)) < TOLERANCE


def test_the_clock_drift_is_taken_out(wearbench_bench, tmp_path):
    """The DAQ's clock runs 20 ppm fast: the raw shift grows by 20 us per second, the latency does not."""
    path, _ = record_taps(wearbench_bench, tmp_path / "taps.mcap", delay=0.3e-3, taps=8)
    result = tt.tap_test(path)
    shifts = np.array([t.shift for t in result.taps])
    latches = np.array([t.latch for t in result.taps])
    slope = np.polyfit(latches, shifts, 1)[0]
    assert slope == pytest.approx(20e-6, rel=0.15)
    assert np.ptp([t.latency for t in result.taps]) < 5e-6


@pytest.mark.parametrize("shift", [0.0, 0.37e-3, 1.234e-3])
def test_the_fit_recovers_a_planted_shift_on_a_filtered_impulse(shift):
    """Synthetic: a half-sine through an 8th-order 3 kHz Butterworth (scipy's lsim of its analogue
    model, a second method to the fit's frequency response), shifted, sampled at 10 kHz with noise."""
    chain = SensorChainStatement(filter="butterworth", filter_order=8, filter_cutoff=3000.0)
    fs, width, latch = 10000.0, 2e-4, 0.05
    b, a = sps.butter(8, 2 * np.pi * 3000.0, analog=True)
    ti = np.arange(0, 0.35, 1 / 400000.0)
    u = np.where((ti >= latch) & (ti <= latch + width), np.sin(np.pi * (ti - latch) / width), 0.0) * 1000.0
    _, y, _ = sps.lsim((b, a), u, ti)
    t = np.arange(0, 0.3, 1 / fs)
    x = np.interp(t - shift, ti, y) + np.random.default_rng(3).normal(0, 0.05, t.size)
    f = np.fft.rfftfreq(t.size, 1 / fs)
    keep = (f >= 1) & (f <= 100)
    measured = np.fft.rfft(x)[keep] / fs
    predicted = 1000.0 * tt.half_sine_spectrum(f[keep], width) * stated_response(chain, f[keep]) * np.exp(
        -2j * np.pi * f[keep] * latch)
    tau, gain, match = tt.fit_shift(measured, predicted, f[keep])
    assert tau == pytest.approx(shift, abs=1e-6)
    assert gain == pytest.approx(1.0, abs=0.01) and match > 0.999


def test_half_sine_spectrum_is_the_pulses_fourier_transform():
    width, fs = 3e-4, 4e6
    t = np.arange(0, width, 1 / fs)
    f = np.array([0.0, 50.0, 400.0, 1500.0])
    direct = np.array([np.sum(np.sin(np.pi * t / width) * np.exp(-2j * np.pi * fk * t)) / fs for fk in f])
    np.testing.assert_allclose(tt.half_sine_spectrum(f, width), direct, rtol=1e-4, atol=1e-10)


def test_a_session_without_taps_is_refused(wearbench_bench, tmp_path, monkeypatch):
    from wearbench.acquisition.backends.sim import SimDrive

    monkeypatch.setattr(SimDrive, "tap", lambda self, *a: None)  # a tapper that never fires
    path, _ = record_taps(wearbench_bench, tmp_path / "quiet.mcap", taps=2)
    with pytest.raises(tt.TapTestError, match=r"quiet\.mcap: no taps recorded"):
        tt.tap_test(path)


def test_a_tap_too_weak_to_see_is_refused(wearbench_bench, tmp_path):
    path, _ = record_taps(wearbench_bench, tmp_path / "weak.mcap", taps=2, tap_peak=0.5)
    with pytest.raises(tt.TapTestError, match=r"weak\.mcap: tap 0 at .* too weak"):
        tt.tap_test(path)


def test_a_clipped_tap_is_refused(wearbench_bench, tmp_path):
    peak = 20 * wearbench_bench.sensor("accelerometer").range
    path, _ = record_taps(wearbench_bench, tmp_path / "hard.mcap", taps=2, tap_peak=peak)
    with pytest.raises(tt.TapTestError, match=r"hard\.mcap: tap 0 .* clipped"):
        tt.tap_test(path)


def test_taps_too_close_are_refused(wearbench_bench, tmp_path):
    path, _ = record_taps(wearbench_bench, tmp_path / "close.mcap", taps=3, tap_interval=0.2)
    with pytest.raises(tt.TapTestError, match=r"close\.mcap: tap 0 .* another tap 0\.2.* between taps"):
        tt.tap_test(path)


def test_an_inconsistent_tap_is_named(wearbench_bench, tmp_path, monkeypatch):
    """One latch 0.3 ms early (a latch of another edge): that tap is named, no latency is given."""
    path, _ = record_taps(wearbench_bench, tmp_path / "taps.mcap", taps=6)
    real = tt.recorded_taps

    def one_off(events):
        taps = real(events)
        return [replace(t, latch=t.latch - 3e-4) if t.number == 3 else t for t in taps]

    monkeypatch.setattr(tt, "recorded_taps", one_off)
    with pytest.raises(tt.TapTestError, match=r"inconsistent taps: tap 3 at"):
        tt.tap_test(path)


def test_a_bench_without_a_chain_statement_is_refused(wearbench_bench, tmp_path):
    path, _ = record_taps(wearbench_bench, tmp_path / "taps.mcap", taps=2)
    bare = replace(wearbench_bench, sensors=tuple(replace(s, chain=None) for s in wearbench_bench.sensors))
    with pytest.raises(tt.TapTestError, match=r"no \[sensor.chain\] statement"):
        tt.tap_test(path, bare)


# ---- the bench file edit ---------------------------------------------------------------------------------

def test_the_latency_edit_changes_only_that_key_and_keeps_comments():
    text = (BENCH_DIR / "ninebar-testbed.toml").read_text()
    new = with_chain_latency(text, 0.512)
    old_lines, new_lines = text.splitlines(), new.splitlines()
    changed = [(a, b) for a, b in zip(old_lines, new_lines, strict=True) if a != b]
    assert len(changed) == 1
    assert changed[0][1].startswith('latency = "0.512 ms"') and "# the rest of the accelerometer" in changed[0][1]


def test_a_missing_latency_key_is_added_under_the_header():
    text = ('[[sensor]]\nname = "enc"\nkind = "encoder"\n[[sensor]]\nname = "acc"  # slider\nkind = "accelerometer"\n'
            '[sensor.chain]   # datasheet\nfilter = "none"\n\n[hardware]\nbackend = "sim"\n')
    new = with_chain_latency(text, -0.004)
    assert '[sensor.chain]   # datasheet\nlatency = "-0.004 ms"\nfilter = "none"' in new
    assert "# slider" in new


def test_an_inline_chain_table_is_not_edited():
    text = '[[sensor]]\nname = "acc"\nkind = "accelerometer"\nchain = { filter = "none", latency = "0 ms" }\n'
    with pytest.raises(ChainEditError, match="no \\[sensor.chain\\] table header"):
        with_chain_latency(text, 0.1)


def test_a_failed_latency_write_leaves_the_bench_file_whole_and_nothing_beside_it(tmp_path, monkeypatch):
    """A full disk (or a Ctrl-C) while the edited bench file is written: the old file stays as it was
    and no temporary file is left beside it."""
    from wearbench.bench.chain_latency import set_chain_latency

    bench = tmp_path / "tb.toml"
    shutil.copy(BENCH_DIR / "ninebar-testbed.toml", bench)
    before = bench.read_bytes()
    write_text = Path.write_text

    def half_then_full_disk(self, data, *args, **kwargs):
        write_text(self, data[: len(data) // 2], *args, **kwargs)
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(Path, "write_text", half_then_full_disk)
    with pytest.raises(OSError, match="No space left"):
        set_chain_latency(bench, 0.5)
    assert bench.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["tb.toml"]


def test_taptest_command_records_and_writes_the_latency_only_when_asked(wearbench_bench, tmp_path, capsys):
    from wearbench.cli import main

    folder = tmp_path / "bench"
    folder.mkdir()
    shutil.copy(BENCH_DIR / "ninebar-testbed.toml", folder / "tb.toml")
    shutil.copytree(BENCH_DIR / "worn", folder / "worn")
    before = (folder / "tb.toml").read_text()
    args = [str(folder / "tb.toml"), "--taps", "4", "--option", "speedup=inf"]
    assert main(["taptest", *args, "--out", str(tmp_path / "t.mcap")]) == 0
    out = capsys.readouterr().out
    assert 'enter under the accelerometer\'s [sensor.chain]:  latency = "' in out
    assert (folder / "tb.toml").read_text() == before  # not asked: not written
    assert main(["taptest", str(folder / "tb.toml"), "--session", str(tmp_path / "t.mcap"), "--write-latency"]) == 0
    latency = load_bench(folder / "tb.toml").sensor("accelerometer").chain.latency
    assert abs(latency) < TOLERANCE  # the shipped truth has no accel_delay
    assert main(["taptest", "ninebar-testbed", "--session", str(tmp_path / "t.mcap"), "--write-latency"]) != 0
    assert "shipped bench" in capsys.readouterr().err
