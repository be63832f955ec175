"""Clearance joints: conservation, restitution, limits, hard cases, failure reports, worn surfaces."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from wearbench.model import SimulationError, build_scene, simulate
from wearbench.model.surfaces import JointSurfaces

from .conftest import disc_bench


def _energy(scene, res, g):
    p = scene.clearance_params("J")
    vx, vy = np.gradient(res.table["J_ex"], res.table["t"]), np.gradient(res.table["J_ey"], res.table["t"])
    pen = np.clip(res.table["J_pen"].to_numpy(), 0, None)
    return 0.5 * (vx**2 + vy**2) - g * res.table["J_ey"] + p["stiffness"] * pen ** 2.5 / 2.5


def test_frictionless_elastic_contact_conserves_energy():
    bench = disc_bench(g=-9.81, ce=1.0, cf=0.0)
    scene = build_scene(bench)
    assert scene.dof == 3
    # start centred with a sideways speed: it falls, bounces around the bearing
    res = simulate(scene, t_end=0.05, output_rate=2e5, rtol=1e-9, atol=1e-13,
                   initial=(np.zeros(3), np.array([0.05, 0.0, 0.0])))
    assert res.summary["peak_fn"]["J"] > 10  # it did hit the bearing
    e = _energy(scene, res, -9.81)[5:-5]
    scale = 0.5 * 0.05**2 + 9.81 * 5e-4
    assert np.ptp(e) / scale < 2e-3


def _rebound(law: str, ce: float, v_in: float = 0.2) -> float:
    scene = build_scene(disc_bench(law=law, ce=ce))
    res = simulate(scene, t_end=0.0035, output_rate=1e6, rtol=1e-9, atol=1e-13,
                   initial=(np.zeros(3), np.array([v_in, 0.0, 0.0])))
    vx = np.gradient(res.table["J_ex"], res.table["t"])
    assert res.table["J_pen"].max() > 0
    return -vx[-10:].mean() / v_in


@pytest.mark.parametrize("law,ce,rel", [("flores", 0.3, 0.2), ("flores", 0.8, 0.06),
                                        ("lankarani-nikravesh", 0.9, 0.03)])
def test_single_impact_restores_the_coefficient_of_restitution(law, ce, rel):
    assert _rebound(law, ce) == pytest.approx(ce, rel=rel)


def test_flores_law_is_the_valid_one_at_low_restitution():
    with pytest.warns(UserWarning):
        ln = _rebound("lankarani-nikravesh", 0.3)
    assert abs(_rebound("flores", 0.3) - 0.3) < 0.5 * abs(ln - 0.3)


def test_low_restitution_with_lankarani_nikravesh_warns():
    with pytest.warns(UserWarning, match="flores"):
        scene = build_scene(disc_bench(ce=0.3))
    assert scene.warnings


def test_contact_onset_at_zero_normal_velocity_settles_to_static_penetration():
    bench = disc_bench(g=-9.81, ce=0.9)
    scene = build_scene(bench)
    p = scene.clearance_params("J")
    c = p["bearing_radius"] - p["journal_radius"]
    # resting exactly on the bearing, at rest: the contact starts with zero normal speed
    res = simulate(scene, t_end=0.05, output_rate=2e4, initial=(np.array([0.0, -c, 0.0]), np.zeros(3)))
    static = (9.81 / p["stiffness"]) ** (1 / 1.5)
    tail = res.table.iloc[-200:]
    assert np.isfinite(res.table.filter(like="J_").to_numpy()).all()
    assert tail["J_fn"].mean() == pytest.approx(9.81, rel=0.02)
    assert tail["J_pen"].mean() == pytest.approx(static, rel=0.05)


def test_tangential_velocity_crossing_zero_under_friction():
    bench = disc_bench(g=-9.81, ce=0.9, cf=0.3)
    scene = build_scene(bench)
    p = scene.clearance_params("J")
    c = p["bearing_radius"] - p["journal_radius"]
    static = (9.81 / p["stiffness"]) ** (1 / 1.5)
    # spinning journal resting on the bearing: friction brakes the spin through vt = 0
    res = simulate(scene, t_end=0.2, output_rate=1e4,
                   initial=(np.array([0.0, -c - static, 0.0]), np.array([0.0, 0.0, 2.0])))
    vt = res.table["J_vt"].to_numpy()
    assert vt[0] > 0.02
    assert np.isfinite(vt).all()
    assert abs(vt[-1]) <= 1e-3  # stopped inside the friction ramp (dead band v0 = 0.1 mm/s, vm = 1 mm/s)
    assert vt.min() > -1e-3  # no reversal beyond the ramp
    assert res.summary["rejected_steps"] < res.summary["steps"]


def test_journal_exactly_centred_at_start(ninebar):
    scene = build_scene(ninebar)
    res = simulate(scene, t_end=0.01, output_rate=1e4)
    first = res.table.iloc[0]
    assert abs(first["A_ex"]) < 1e-12 and abs(first["A_ey"]) < 1e-12 and first["A_fn"] == 0
    assert np.isfinite(res.table.to_numpy()).all()


def test_clearance_shrinking_to_zero_converges_to_ideal(slider_crank):
    ideal = simulate(build_scene(slider_crank, clearances={"S": None}), revolutions=0.5, output_rate=1e5)
    errs = []
    for c in (1e-4, 1e-5, 1e-6):
        r = simulate(build_scene(slider_crank, clearances={"S": c}), revolutions=0.5, output_rate=1e5)
        errs.append(np.abs(r.table["slider_pos"] - ideal.table["slider_pos"]).max())
    assert errs[0] > errs[1] > errs[2]
    assert errs[2] < 1e-5


@pytest.mark.parametrize("clearance", [1e-6, 1e-3])
def test_extreme_clearances_run_clean(slider_crank, clearance):
    scene = build_scene(slider_crank, clearances={"S": clearance})
    res = simulate(scene, revolutions=1.0)
    assert np.isfinite(res.table.to_numpy()).all()
    assert res.summary["max_constraint_drift"] < 1e-9
    assert 0 < res.summary["peak_fn"]["S"] < 1e6
    assert res.table["S_pen"].max() < 3e-4  # a hard Hertz impact at several m/s, not a blow-up


def test_fast_crank_twenty_pi(ninebar):
    res = simulate(build_scene(ninebar), speed=-20 * np.pi, revolutions=0.5)
    assert np.isfinite(res.table.to_numpy()).all()
    assert res.summary["peak_fn"]["A"] > 0
    assert res.summary["max_constraint_drift"] < 1e-9


@pytest.mark.slow
def test_hundred_revolutions_without_drift_growth(slider_crank):
    scene = build_scene(slider_crank)
    res = simulate(scene, revolutions=100, output_rate=2e4)
    assert res.summary["max_constraint_drift"] < 1e-10
    rev = res.poincare(("S_ex", "S_ey"))
    assert len(rev) == 100
    assert (np.hypot(rev["S_ex"], rev["S_ey"]) < 0.5e-3 + 1e-4).all()


def test_papers_method_blowing_up_raises_simulation_error(ninebar):
    # the paper's RK4 at 1e-4 s is unstable with the conformal contact stiffness: stop, never garbage
    with pytest.raises(SimulationError) as info:
        simulate(build_scene(ninebar), method="rk4-paper", revolutions=0.5)
    err = info.value
    assert 0 < err.t < 0.2
    assert "t = " in str(err) and err.state
    assert err.quantity


def test_unworn_surfaces_reproduce_the_even_clearance_model(slider_crank):
    even = simulate(build_scene(slider_crank), revolutions=0.5)
    worn0 = simulate(build_scene(slider_crank, surfaces={"S": JointSurfaces.unworn(1000)}), revolutions=0.5)
    pd.testing.assert_frame_equal(even.table, worn0.table, check_exact=True)
    # the worn-geometry code path with vanishing wear agrees with the even model before impacts diverge
    tiny = JointSurfaces(np.full(1000, 1e-15), np.zeros(1000))
    tight = {"revolutions": 0.05, "rtol": 1e-10, "atol": 1e-13}
    worn = simulate(build_scene(slider_crank, surfaces={"S": tiny}), **tight)
    even = simulate(build_scene(slider_crank), **tight)
    np.testing.assert_allclose(worn.table["slider_pos"], even.table["slider_pos"], atol=1e-9)


def test_uniform_bearing_wear_acts_as_a_larger_clearance(slider_crank):
    """In contact and near it the penetration is |e| - (c + h) exactly; a gap wider than the
    search's margin is the best bearing midpoint's, at most |e| (1 - cos(cell / 2)) smaller."""
    h, n = 1e-4, 100
    worn = JointSurfaces(np.full(n, h), np.zeros(n))
    a = simulate(build_scene(slider_crank, surfaces={"S": worn}), revolutions=0.3, output_rate=1e5)
    emag = np.hypot(a.table["S_ex"], a.table["S_ey"]).to_numpy()
    excess = emag - a.table["S_pen"].to_numpy() - (0.5e-3 + h)
    near = a.table["S_pen"].to_numpy() > -1e-6
    assert near.sum() > 100 and (~near).sum() > 100
    assert np.abs(excess[near]).max() < 1e-12
    assert excess.min() > -1e-12 and (excess - emag * (1 - np.cos(np.pi / n))).max() < 1e-12


def test_record_contacts_gives_one_row_per_accepted_step(slider_crank):
    res = simulate(build_scene(slider_crank), revolutions=0.3, record_contacts=True)
    rec = res.contacts["S"]
    assert list(rec.columns) == ["t", "dt", "fn", "vt", "omega_rel", "phi_bearing", "phi_journal", "pen"]
    assert len(rec) == res.summary["steps"]
    assert rec["dt"].sum() == pytest.approx(res.summary["t_end"])
    assert (rec["fn"] > 0).any() and (rec["phi_bearing"].between(0, 2 * np.pi)).all()
    assert simulate(build_scene(slider_crank), revolutions=0.1).contacts is None
