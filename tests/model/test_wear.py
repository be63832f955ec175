"""Archard wear laws (model/wear.py) against closed-form results and conservation of volume."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.model.contact import effective_modulus
from wearbench.model.wear import (
    WearLaw,
    accumulate_wear,
    deposit_arcs,
    worn_volume,
)

E_STEEL = effective_modulus(206e9, 0.3, 206e9, 0.3)
R1, R2, L, KN = 0.015, 0.0144, 0.02, 5e-15


def law(**kw) -> WearLaw:
    return WearLaw(KN, R1, R2, L, E_STEEL, **kw)


def rotating_journal(fn: float, omega: float, t_end: float, dt: float = 1e-4, phi_b: float = 1.0) -> pd.DataFrame:
    """Journal turning at ``omega`` (rad/s) in a fixed bearing, pressed with ``fn`` towards bearing
    angle ``phi_b``: the contact stays at phi_b on the bearing and runs round the journal."""
    t = np.arange(round(t_end / dt)) * dt
    return pd.DataFrame({"t": t, "dt": dt, "fn": fn, "vt": R2 * omega, "omega_rel": omega,
                         "phi_bearing": phi_b, "phi_journal": np.mod(phi_b - omega * t, 2 * np.pi),
                         "pen": 1e-6})


def test_pressure_is_mean_hertz_line_pressure():
    # Johnson (1985) eq. 4.45: peak p0 = sqrt(P' E*/(pi R*)), P' = F/L; mean = (pi/4) p0.
    fn = 1234.0
    r_eff = R1 * R2 / (R1 - R2)
    p0 = math.sqrt(fn / L * E_STEEL / (math.pi * r_eff))
    assert law().pressure(fn) == pytest.approx(math.pi / 4 * p0, rel=1e-12)
    assert law().pressure(0.0) == 0.0


def test_constant_load_rotating_journal_matches_closed_form():
    fn, omega, revs = 800.0, 4 * math.pi, 10
    t_end = revs * 2 * math.pi / omega
    w = law(split=0.5, footprint="hertz")
    s = accumulate_wear(rotating_journal(fn, omega, t_end), w, 1000)
    # Archard (eq. 17) integrated at constant P: h = K_n P S, S = R1 omega t
    h = KN * w.pressure(fn) * R1 * omega * t_end
    b = w.half_width(fn)
    region_b = int(1.0 / (2 * math.pi) * 1000)
    assert s.bearing[region_b] == pytest.approx(0.5 * h, rel=1e-9)
    assert s.bearing.max() == pytest.approx(0.5 * h, rel=1e-9)
    # bearing footprint: depth over an arc 2b only
    assert np.count_nonzero(s.bearing) * 2 * math.pi * R1 / 1000 == pytest.approx(2 * b, abs=2 * 2 * math.pi * R1 / 1000)
    # journal: the contact runs round it whole revolutions: uniform h/2 x (2b / circumference)
    np.testing.assert_allclose(s.journal, 0.5 * h * 2 * b / (2 * math.pi * R2), rtol=2e-3)


def test_pressure_footprint_is_the_elastic_foundation_profile_of_the_overlap():
    """Unworn surfaces, journal pressed towards bearing angle 1 rad with penetration d: the overlap
    is o(x) = (c + d) cos x - c over |x| < acos(c/(c + d)), so the bearing depth is the Archard
    volume V/2 spread in proportion to it (closed form; binning costs < 1 % at the peak)."""
    fn, omega, t_end, pen = 800.0, 4 * math.pi, 2.0, 20e-6
    w = law(split=0.5)
    s = accumulate_wear(rotating_journal(fn, omega, t_end).assign(pen=pen), w, 1000)
    vol = KN * fn * R1 * omega * t_end
    assert worn_volume(s, w) == pytest.approx(vol, rel=1e-9)
    c = R1 - R2
    e = c + pen
    x0 = math.acos(c / e)
    integral = 2 * (e * math.sin(x0) - c * x0)  # of o(x) dx
    phi = 2 * np.pi * (np.arange(1000) + 0.5) / 1000 - 1.0
    want = 0.5 * vol / (L * R1) * np.maximum(e * np.cos(phi) - c, 0.0) / integral
    assert s.bearing.max() == pytest.approx(want.max(), rel=1e-2)
    np.testing.assert_allclose(s.bearing, want, atol=3e-2 * want.max())
    # arc narrower than the old Hertz width would be: wider than one region, well inside 90 deg
    assert 5 < np.count_nonzero(s.bearing) < 250


def test_split_moves_depth_between_surfaces():
    rec = rotating_journal(500.0, 3.0, 1.0)
    all_b = accumulate_wear(rec, law(split=1.0))
    all_j = accumulate_wear(rec, law(split=0.0))
    assert all_j.bearing.max() == 0 and all_b.journal.max() == 0
    assert worn_volume(all_b, law()) == pytest.approx(worn_volume(all_j, law()), rel=1e-9)


@pytest.mark.parametrize("sliding", ["rotation", "tangential"])
def test_no_load_or_no_sliding_no_wear(sliding):
    rec = rotating_journal(900.0, 5.0, 0.5)
    zero_load = rec.assign(fn=0.0)
    no_slide = rec.assign(omega_rel=0.0, vt=0.0)
    for r in (zero_load, no_slide, rec.assign(fn=-10.0)):
        s = accumulate_wear(r, law(sliding=sliding))
        assert s.bearing.max() == 0 and s.journal.max() == 0


def test_sliding_choices_differ_only_by_the_distance():
    rec = rotating_journal(900.0, 5.0, 0.5)
    rot = accumulate_wear(rec, law(sliding="rotation"))
    tan = accumulate_wear(rec, law(sliding="tangential"))
    np.testing.assert_allclose(tan.bearing, rot.bearing * R2 / R1, rtol=1e-12)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.floats(1, 5000), st.floats(0, 40), st.floats(-10, 10), st.floats(-10, 10)),
                min_size=1, max_size=30))
def test_worn_volume_equals_archard_volume(steps):
    fn, om, pb, pj = (np.array(x) for x in zip(*steps, strict=True))
    rec = pd.DataFrame({"t": np.arange(fn.size) * 1e-4, "dt": 1e-4, "fn": fn, "vt": 0.0, "omega_rel": om,
                        "phi_bearing": pb, "phi_journal": pj, "pen": fn * 1e-8})
    archard = KN * np.sum(fn * R1 * np.abs(om) * 1e-4)  # eq. 15: V = K_n F S
    for footprint in ("pressure", "hertz"):
        w = law(footprint=footprint)
        s = accumulate_wear(rec, w, 1000)
        assert worn_volume(s, w) == pytest.approx(archard, rel=1e-9, abs=1e-30)


def test_region_footprint_is_the_papers_single_region():
    rec = rotating_journal(800.0, 4 * math.pi, 0.5)
    w = law(footprint="region")
    s = accumulate_wear(rec, w, 1000)
    assert np.count_nonzero(s.bearing) == 1
    h = KN * w.pressure(800.0) * R1 * 4 * math.pi * 0.5
    assert s.bearing.max() == pytest.approx(0.5 * h, rel=1e-9)


@settings(max_examples=60, deadline=None)
@given(st.floats(0, 100, exclude_max=True), st.floats(0.001, 20), st.floats(1e-9, 1e-3))
def test_deposit_matches_brute_force_overlap(centre, half, depth):
    n = 100
    got = deposit_arcs(n, np.array([centre]), np.array([half]), np.array([depth]))
    x = (np.arange(200_000) + 0.5) / 2000.0  # fine grid over [0, n), 2000 points per region
    inside = np.abs((x - centre + n / 2) % n - n / 2) <= half
    want = depth * inside.reshape(n, -1).mean(axis=1)
    np.testing.assert_allclose(got, want, atol=depth * 2e-3)
    assert got.sum() == pytest.approx(depth * 2 * half, rel=1e-9)


def test_law_from_bench_and_bad_settings():
    bench = load_bench(shipped_bench("ninebar"))
    w = WearLaw.from_bench(bench.with_clearances({"A": 0.3e-3}), "A")
    assert (w.bearing_radius, w.journal_radius, w.axial_length) == pytest.approx((0.015, 0.0147, 0.02))
    assert w.coefficient == bench.wear.coefficient and w.split == bench.wear.split
    with pytest.raises(ValueError, match="split = 1.5"):
        law(split=1.5)
    with pytest.raises(ValueError, match="sliding = 'x'"):
        law(sliding="x")
    with pytest.raises(ValueError, match="no clearance"):
        WearLaw.from_bench(bench, "C")
    with pytest.raises(ValueError, match="lacks columns"):
        accumulate_wear(pd.DataFrame({"fn": [1.0]}), law())
