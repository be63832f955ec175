"""Worn-surface contract: validation, .npz round trip, interpolation, loading from a bench file."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import PchipInterpolator
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.model.surface_tables import depth_at, depth_eval
from wearbench.model.surfaces import (
    JointSurfaces,
    SurfaceError,
    region_of,
    surfaces_from_bench,
)


def test_kernel_depth_is_the_contract_curve_and_c1():
    """The kernel's depth and slope are the contract's PCHIP and its derivative, continuous across
    every region centre (the normal and the penetration of a worn joint are continuous)."""
    rng = np.random.default_rng(3)
    d = np.zeros(200)
    d[80:110] = rng.random(30) * 1e-4  # a rough pit
    phi = np.linspace(0.0, 2 * np.pi, 3001)
    got = np.array([depth_eval(d, d.size, p) for p in phi])
    np.testing.assert_allclose(got[:, 0], depth_at(d, phi), rtol=1e-12, atol=1e-20)
    eps = 1e-7
    fd = (depth_at(d, phi + eps) - depth_at(d, phi - eps)) / (2 * eps)
    np.testing.assert_allclose(got[:, 1], fd, rtol=1e-5, atol=1e-9)
    centres = 2 * np.pi * (np.arange(d.size) + 0.5) / d.size
    left = np.array([depth_eval(d, d.size, c - 1e-10)[1] for c in centres])
    right = np.array([depth_eval(d, d.size, c + 1e-10)[1] for c in centres])
    assert np.max(np.abs(left - right)) < 1e-6 * np.max(np.abs(got[:, 1]))


def test_round_trip(tmp_path):
    rng = np.random.default_rng(1)
    s = JointSurfaces(rng.random(1000) * 1e-5, rng.random(1000) * 2e-5, 4e5, "second wear", {"joint": "B"})
    path = s.save(tmp_path / "b")  # suffix added
    assert path.suffix == ".npz"
    t = JointSurfaces.load(path)
    np.testing.assert_array_equal(t.bearing, s.bearing)
    np.testing.assert_array_equal(t.journal, s.journal)
    assert (t.cycles, t.label, t.meta) == (4e5, "second wear", {"joint": "B"})


@pytest.mark.parametrize(("bearing", "message"), [
    (np.array([0.0, -1e-6, 0.0]), r"bearing\[1\] = -1e-06 m: expected depths >= 0"),
    (np.array([0.0, np.nan, 0.0]), r"bearing\[1\] = nan: expected finite"),
    (np.zeros((3, 3)), r"shape \(3, 3\): expected a 1-D array"),
    (np.zeros(2), r"at least 3 regions"),
])
def test_bad_depths_named(bearing, message):
    with pytest.raises(SurfaceError, match=message):
        JointSurfaces(bearing, np.zeros(3))


def test_bad_file_named(tmp_path):
    bad = tmp_path / "x.npz"
    np.savez(bad, bearing=np.zeros(4))
    with pytest.raises(SurfaceError, match=r"x\.npz: format = ''"):
        JointSurfaces.load(bad)
    (tmp_path / "junk.npz").write_text("not a zip")
    with pytest.raises(SurfaceError, match="junk.npz: not a worn-surface"):
        JointSurfaces.load(tmp_path / "junk.npz")
    with pytest.raises(OSError, match="does not exist"):
        JointSurfaces.load(tmp_path / "missing.npz")


def test_region_centres_and_periodicity():
    d = np.array([0.0, 1.0, 4.0, 2.0])
    centres = 2 * np.pi * (np.arange(4) + 0.5) / 4
    np.testing.assert_allclose(depth_at(d, centres), d)
    np.testing.assert_allclose(depth_at(d, centres + 2 * np.pi), d)
    # across angle 0 (last to first centre): scipy's PCHIP through the periodically extended nodes
    ext = np.concatenate([d[-2:], d, d[:2]])
    x = 2 * np.pi * (np.arange(-2, 6) + 0.5) / 4
    ref = PchipInterpolator(x, ext)
    phi = np.linspace(-0.5, 0.5, 41)
    np.testing.assert_allclose(depth_at(d, phi), ref(phi), rtol=1e-12, atol=1e-15)
    assert region_of(2 * np.pi - 1e-9, 4) == 3
    assert region_of(-1e-9, 4) == 3


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(0, 1e-4), min_size=3, max_size=50), st.floats(-20, 20))
def test_interpolation_is_bounded_by_neighbours(depths, phi):
    d = np.array(depths)
    v = depth_at(d, phi)
    n = d.size
    i = int(np.floor(np.mod(phi, 2 * np.pi) * n / (2 * np.pi) - 0.5)) % n
    lo, hi = sorted((d[i], d[(i + 1) % n]))
    assert lo - 1e-18 <= v <= hi + 1e-18


def test_surfaces_from_bench(tmp_path):
    src = shipped_bench("ninebar").read_text()
    s = JointSurfaces(np.full(1000, 1e-6), np.zeros(1000), 2e5, "first wear")
    s.save(tmp_path / "A.npz")
    text = src.replace('axial_length = "20 mm"         # FILLED IN',
                       'axial_length = "20 mm"\nsurfaces = "A.npz"', 1)
    assert text != src
    (tmp_path / "worn.toml").write_text(text)
    bench = load_bench(tmp_path / "worn.toml")
    got = surfaces_from_bench(bench)
    assert list(got) == ["A"]
    assert got["A"].label == "first wear" and got["A"].bearing[0] == 1e-6
    (tmp_path / "A.npz").write_bytes(b"broken")
    with pytest.raises(SurfaceError, match=r"worn\.toml: joint A\.clearance\.surfaces"):
        surfaces_from_bench(bench)


def test_shipped_worn_surfaces_load():
    worn = shipped_bench("ninebar").parent / "worn"
    for j in ("A", "B"):
        first = JointSurfaces.load(worn / f"ninebar-testbed_{j}_200k.npz")
        second = JointSurfaces.load(worn / f"ninebar-testbed_{j}_400k.npz")
        assert (first.cycles, second.cycles) == (200_000, 400_000)
        assert first.bearing.size == first.journal.size == 1000
        # wear only accumulates: the second state is at least as deep everywhere
        assert (second.bearing >= first.bearing).all() and (second.journal >= first.journal).all()
        assert first.meta["joint"] == j and first.meta["bench"] == "ninebar-testbed"


def test_reachable_depth_of_a_pit_the_counter_body_fits_and_of_a_spike():
    """A pit cut by the counter-body itself (h = e cos(phi) - c around phi = 0, e = c + D) is reached
    to its full depth D; a one-region spike of the same depth hardly at all (its walls are far
    steeper than the relative curvature of a circle in a circle)."""
    from wearbench.model.surfaces import reachable_depth

    c, depth, n = 0.6e-3, 50e-6, 2000
    phi = 2 * np.pi * (np.arange(n) + 0.5) / n
    fitted = np.maximum((c + depth) * np.cos(phi - 1.0) - c, 0.0)
    assert reachable_depth(fitted, c) == pytest.approx(fitted.max(), rel=2e-3)
    spike = np.zeros(n)
    spike[700] = depth
    assert reachable_depth(spike, c) < 0.01 * depth
    assert reachable_depth(np.zeros(n), c) == 0.0
