"""CFC and Butterworth filters: measured gain against the design response, zero phase, window edges."""

import numpy as np
import pytest
from scipy import signal
from wearbench.validation.measurement.filters import (
    CFC_CLASSES,
    FilterSpec,
    apply_filter,
    cfc_coefficients,
    cfc_gain,
    pad_length,
    parse_filter,
)

pytestmark = pytest.mark.no_kernels

FS = 10_000.0


def measured_gain(spec: FilterSpec, f: float, fs: float = FS) -> tuple[float, float]:
    """Gain and phase (rad) of a long sine through the filter, read in the middle by least squares."""
    n = int(fs * 2)
    t = np.arange(n) / fs
    y = apply_filter(np.sin(2 * np.pi * f * t), fs, FilterSpec(kind=spec.kind, cfc=spec.cfc, cutoff=spec.cutoff,
                                                               order=spec.order, remove_bias=False))
    mid = slice(n // 4, 3 * n // 4)
    basis = np.column_stack([np.sin(2 * np.pi * f * t[mid]), np.cos(2 * np.pi * f * t[mid])])
    (s, c), *_ = np.linalg.lstsq(basis, y[mid], rcond=None)
    return float(np.hypot(s, c)), float(np.arctan2(c, s))


@pytest.mark.parametrize("cfc", CFC_CLASSES)
def test_cfc_measured_gain_matches_design_response(cfc):
    for f in (0.1 * cfc, 0.5 * cfc, cfc, 1.65 * cfc, 3 * cfc):
        if f >= FS / 2:
            continue
        gain, phase = measured_gain(FilterSpec(kind="cfc", cfc=cfc), f)
        assert gain == pytest.approx(cfc_gain(f, cfc, FS), rel=1e-3, abs=1e-5)
        assert abs(phase) < 1e-3  # zero phase


@pytest.mark.parametrize("cfc", CFC_CLASSES)
def test_cfc_design_response_is_j211(cfc):
    """The design response itself, against J211-1's own corridor numbers (independent of the code):
    flat (+0.5/-1 dB) up to CFC, and -3 dB near 1.65 CFC (J211 F_N corner 1.667 CFC), at a sample
    rate well above J211's minimum (bilinear warping grows as CFC approaches the Nyquist frequency)."""
    fs = 50.0 * cfc
    f = np.linspace(0.1, cfc, 50)
    db = 20 * np.log10(cfc_gain(f, cfc, fs))
    assert np.all(db <= 0.5) and np.all(db >= -1.0)
    grid = np.linspace(cfc, 2.5 * cfc, 20_000)
    cross = grid[np.argmin(np.abs(20 * np.log10(cfc_gain(grid, cfc, fs)) + 3.0))]
    assert cross == pytest.approx(1.65 * cfc, rel=0.03)


def test_cfc_coefficients_are_the_bilinear_butterworth():
    """J211's explicit coefficients equal scipy's bilinear 2nd-order Butterworth at 2.0775 CFC."""
    b, a = cfc_coefficients(180, FS)
    b_ref, a_ref = signal.butter(2, 180 * 2.0775, fs=FS)
    assert np.allclose(b, b_ref, rtol=1e-10) and np.allclose(a, a_ref, rtol=1e-10)


def test_butterworth_zero_phase_gain():
    spec = FilterSpec(kind="butter", cutoff=200.0, order=4)
    for f in (20.0, 200.0, 400.0):
        gain, phase = measured_gain(spec, f)
        _, h = signal.freqz(*signal.butter(4, 200.0, fs=FS), worN=[f], fs=FS)
        assert gain == pytest.approx(abs(h[0]) ** 2, rel=1e-3, abs=1e-6)
        assert abs(phase) < 1e-3


def test_window_cut_from_padded_segment_equals_whole_record():
    """Filtering a window with the padding margin gives the same interior as filtering the record."""
    rng = np.random.default_rng(1)
    x = np.cumsum(rng.normal(size=40_000))
    x -= x.mean()
    spec = FilterSpec(kind="cfc", cfc=60, remove_bias=False)
    whole = apply_filter(x, FS, spec)
    pad = pad_length(spec, FS)
    a, b = 15_000, 25_000
    part = apply_filter(x[a - pad: b + pad], FS, spec)[pad:-pad]
    scale = np.max(np.abs(whole[a:b]))
    assert np.max(np.abs(part - whole[a:b])) < 1e-3 * scale


def test_bias_and_trend_removal():
    t = np.arange(5000) / FS
    x = np.sin(2 * np.pi * 10 * t)
    assert np.allclose(apply_filter(x + 3.0, FS, FilterSpec(kind="none")), x - x.mean())
    detrended = apply_filter(x + 2.0 + 50 * t, FS, FilterSpec(kind="none", detrend=True))
    assert np.allclose(detrended, signal.detrend(x), atol=1e-9)


def test_parse_filter():
    assert parse_filter("cfc600").cfc == 600
    assert parse_filter("butter:150").cutoff == 150 and parse_filter("butter:150:2").order == 2
    assert parse_filter("none").kind == "none"
    for bad in ("cfc100", "butter", "butter:-1", "lowpass"):
        with pytest.raises(ValueError, match="filter"):
            parse_filter(bad)
    with pytest.raises(ValueError, match="sample rate"):
        apply_filter(np.zeros(100), 1000.0, parse_filter("cfc1000"))
