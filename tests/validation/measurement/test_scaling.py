"""Issue 44, item 1: the analysis in the bench's own terms. Features, kept curves, drawn mounts, model
output rate and windows resolve per bench and speed from crank orders and the sensor chain, a bench
file's ``[analysis]`` table overrides them, and the test bed at its 1 Hz resolves to exactly the
analysis its shipped ensembles and estimator were built with."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from wearbench.bench.content import bench_key
from wearbench.bench.load import load_bench, parse_bench, shipped_bench
from wearbench.bench.schema import BenchError
from wearbench.validation.comparison.windows import WindowOptions, window_theory
from wearbench.validation.estimation.estimate import EstimatorDesign
from wearbench.validation.inference.ensemble import Ensemble, EnsembleSettings
from wearbench.validation.inference.sensor_path import PathSpread, SensorPath
from wearbench.validation.measurement.features import FeatureSpec
from wearbench.validation.measurement.scaling import resolve_analysis

TESTBED = load_bench(shipped_bench("ninebar-testbed"))
SLIDER = load_bench(shipped_bench("slider-crank"))
RPM = 2 * math.pi / 60


def flat(bands) -> list[float]:
    return [x for band in bands for x in band]


def with_table(bench, table: str):
    return parse_bench(bench.source + "\n" + table, bench.path)


def test_the_test_bed_resolves_to_the_analysis_its_shipped_theory_was_built_with():
    a = resolve_analysis(TESTBED)
    assert a.crank_hz == 1.0 and a.features == FeatureSpec() and a.curve_filter == "cfc180"
    assert a.cap == pytest.approx(2100.0) and "anti-alias filter" in a.cap_source  # above its 1 kHz top band
    assert a.output_rate == 20_000.0 and a.window_lowpass == 10.0 and a.validated
    assert EnsembleSettings.for_bench(TESTBED) == EnsembleSettings()
    assert EnsembleSettings.for_bench(TESTBED, realisations=48) == EstimatorDesign().settings
    assert EstimatorDesign.for_bench(TESTBED) == EstimatorDesign()
    assert EstimatorDesign.for_bench(TESTBED, small=True) == EstimatorDesign.small()
    assert PathSpread.around(FeatureSpec()) == PathSpread()
    assert WindowOptions().for_crank(a.crank_hz, a.window_lowpass) == WindowOptions()


def test_the_default_prior_is_unchanged_on_the_test_bed():
    """The sensor-path prior now follows the bands; on the test bed's it is the one it always was."""
    spec = FeatureSpec()
    assert SensorPath.prior(spec) == SensorPath.prior(spec, PathSpread())
    assert "300-3000 Hz" in SensorPath.prior(spec).source


def test_the_slider_crank_at_5000_rpm_looks_above_its_kinematics_and_below_its_sensor_chain():
    a = resolve_analysis(SLIDER)
    f = 5000 / 60
    assert a.crank_hz == pytest.approx(f)
    assert a.features.lowpass == 1000.0  # 50 orders (4.2 kHz) capped: the curve must not follow single impacts
    # cut where its shock accelerometer (100 kHz mounted) still reads within 5 %, below its 30 kHz filter's roll-off
    assert flat(a.features.bands) == pytest.approx([50 * f, 150 * f, 150 * f, 20_000.0])
    assert a.cap == 20_000.0 and "resonance 100 kHz" in a.cap_source
    assert any("left out" in t for t in a.left_out) and any("cut at 20 kHz" in t for t in a.left_out)
    assert a.output_rate == 400_000.0 and a.curve_filter == "butter:20000:2"
    assert a.window_lowpass == pytest.approx(10 * f)
    assert EnsembleSettings.for_bench(SLIDER).sensor_paths == PathSpread(mode=(6000.0, 60000.0))


def test_at_120_rpm_the_same_bench_scales_its_bands_down_in_crank_orders():
    a = resolve_analysis(SLIDER, 120 * RPM)
    assert a.features.lowpass == pytest.approx(100.0)
    assert flat(a.features.bands) == pytest.approx([100.0, 300.0, 300.0, 800.0, 800.0, 2000.0])
    assert not a.left_out and a.curve_filter == "butter:747.9:2"
    assert a.output_rate == pytest.approx(40_000.0)


def test_the_analysis_table_overrides_each_rule_and_is_not_physics():
    own = with_table(SLIDER, '[analysis]\nbins = 24\nlowpass = "800 Hz"\nbands = [["2 kHz", "6 kHz"], [80, 200]]\n'
                             'window_lowpass = 5\nspeeds = ["100 rpm", "6000 rpm"]\n')
    a = resolve_analysis(own)
    f = 5000 / 60
    assert a.features.bins == 24 and a.features.lowpass == 800.0
    assert flat(a.features.bands) == pytest.approx([2000.0, 6000.0, 80 * f, 200 * f])
    assert a.window_lowpass == pytest.approx(5 * f)
    assert a.speeds == pytest.approx((100 / 60, 6000 / 60)) and "[analysis] speeds" in a.speeds_source
    assert bench_key(own) == bench_key(SLIDER)  # cached simulations stay valid


@pytest.mark.parametrize(("table", "key"), [
    ("bands = [[150, 50]]", "analysis.bands[0]"),
    ("bands = [[50, '150 Hz']]", "analysis.bands[0]"),
    ("lowpass = -3", "analysis.lowpass"),
    ("lowpass = '50 m'", "analysis.lowpass"),
    ("speeds = ['2000 rpm', '100 rpm']", "analysis.speeds"),
    ("bins = 2", "analysis.bins"),
    ("order = 3", "analysis.order"),
])
def test_a_bad_analysis_table_is_refused_naming_the_key(table, key):
    with pytest.raises(BenchError, match=key.replace("[", r"\[").replace("]", r"\]")):
        with_table(SLIDER, f"[analysis]\n{table}\n")


def test_a_speed_the_sensor_chain_cannot_see_is_refused_naming_speed_and_cap():
    slow = parse_bench(TESTBED.source.replace('sample_rate = "10 kHz"', 'sample_rate = "100 Hz"', 1), TESTBED.path)
    with pytest.raises(ValueError, match=r"1 Hz crank .* every impact band lies above .* 45 Hz .*cannot see impacts"):
        resolve_analysis(slow)
    with pytest.raises(ValueError, match="cannot see impacts"):
        EnsembleSettings.for_bench(slow)


def test_a_speed_outside_the_validated_ones_gets_a_note():
    assert resolve_analysis(SLIDER).speed_note() is None
    note = resolve_analysis(SLIDER, 10 * RPM).speed_note()
    assert "10 rpm lies outside the 60-5000 rpm" in note
    own = with_table(SLIDER, '[analysis]\nspeeds = ["4000 rpm", "5000 rpm"]\n')
    assert "[analysis] speeds" in resolve_analysis(own, 3000 * RPM).speed_note()


def test_windows_scale_their_low_passes_and_delay_search_with_the_crank():
    w = WindowOptions().for_crank(50.0)
    assert (w.lowpass, w.delay_lowpass) == (500.0, 500.0)
    assert w.delay_floor == pytest.approx(7.5e-4 / 50) and w.max_delay == WindowOptions().max_delay
    assert w.delay_step == pytest.approx(max(2.5e-5 / 50, 2e-3 / 2000))


def test_windows_of_six_cycle_realisations_at_5000_rpm_need_no_longer_rows():
    """The windows' slow curves of an ensemble of 6 cycles at the slider-crank's speed (its filter pads
    by a row's length: scipy's 'padlen' refused them before)."""
    a = resolve_analysis(SLIDER)
    rng = np.random.default_rng(0)
    m, c, grid = 6, 6, 720
    t = np.arange(c * grid) / grid
    curves = (np.sin(2 * np.pi * t)[None] + 0.1 * rng.normal(size=(m, c * grid))).reshape(m, c, grid)
    settings = replace(EnsembleSettings.for_bench(SLIDER, realisations=m, cycles=c), sensor_paths=None)
    ens = Ensemble("s", settings, rng.normal(size=(m, c, settings.features.size)), curves, rng.normal(size=(m, c)),
                   SLIDER.speed)
    options = WindowOptions(statistic="z2").for_crank(a.crank_hz, a.window_lowpass)
    theory = window_theory(ens, crank_speed=SLIDER.speed, options=options)
    assert theory.null["z2"].size == m * 2 and np.all(np.isfinite(theory.reference.slow_mean))


def _session(bench, revolutions=4, fs=100_000.0, speed=None, full_scale=None, impact=5e3):
    """A session of ``bench`` at its speed (or ``speed``): a once-per-revolution impact in the
    acceleration; ``full_scale``: its recorded range (m/s^2)."""
    import pandas as pd
    from wearbench.acquisition.layout import clip_level
    from wearbench.validation.measurement.session import MeasuredSession

    bench = bench if speed is None else bench.with_speed(speed)

    omega = abs(bench.speed)
    t = np.arange(int(revolutions * 2 * np.pi / omega * fs)) / fs
    angle = omega * t + 0.3
    acc = 10.0 * np.sin(angle) + impact * np.exp(-((np.mod(angle, 2 * np.pi) - 2.0) / 0.01) ** 2)
    enc_t = t[::10]
    return MeasuredSession("s", pd.DataFrame({"time": t, "acc": acc}),
                           pd.DataFrame({"time": enc_t, "angle": omega * enc_t + 0.3}), bench=bench,
                           metadata={"session": {"speed_rad_s": str(bench.speed)}},
                           clip_level=None if full_scale is None else clip_level(full_scale))


def test_features_read_the_accelerometer_at_its_stated_delay_where_it_moves_a_feature():
    """At 5000 rpm the slider-crank's stated 27 us chain is 0.8 degrees of crank: its sessions' samples
    are read at the crank angle that much earlier; the test bed's 0.27 ms at 1 Hz (0.1 degree) is not."""
    from wearbench.validation.measurement.features import cycle_features

    slider = _session(SLIDER, revolutions=6)
    spec = resolve_analysis(SLIDER).features
    delay = slider.feature_delay(spec)
    assert delay is not None and delay.min() == pytest.approx(slider.stated_delay().constant, rel=1e-3)
    t, _, acc = slider.samples
    shifted = cycle_features(t, np.interp(t - delay, slider.encoder["time"], slider.encoder["angle"]), acc, spec)
    assert np.array_equal(slider.features(spec).values, shifted.values)
    assert not np.array_equal(slider.features(spec).values, cycle_features(*slider.samples, spec).values)
    testbed = _session(TESTBED, revolutions=3, fs=10_000.0)
    assert testbed.feature_delay(FeatureSpec()) is None
    assert np.array_equal(testbed.features().values, cycle_features(*testbed.samples, FeatureSpec()).values)


def test_a_range_too_coarse_for_the_motion_is_said():
    """A 50,000 g range records in 15 m/s^2 steps: the 20 m/s^2 span of the slider-crank's motion at 120
    rpm is about one of them; at 500 g it is 130."""
    g = 9.80665
    coarse = _session(SLIDER, revolutions=3, speed=120 * RPM, full_scale=50_000 * g, fs=20_000.0, impact=0.0)
    note = coarse.resolution_note(coarse.features())
    assert note and "steps of its 15 m/s^2 resolution (its 50,000 g range over 32768)" in note
    fine = _session(SLIDER, revolutions=3, speed=120 * RPM, full_scale=500 * g, fs=20_000.0, impact=0.0)
    assert fine.resolution_note(fine.features()) is None
    unknown = _session(SLIDER, revolutions=3, speed=120 * RPM, fs=20_000.0, impact=0.0)  # no recorded range
    assert unknown.resolution_note(unknown.features()) is None
