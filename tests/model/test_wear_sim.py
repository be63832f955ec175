"""Wear on the real model: unworn surfaces change nothing, sharp steps do not break the integrator,
a simulated stage conserves the Archard volume; the `wear` command writes its files (`study`: test_study.py)."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.cli import main
from wearbench.model import build_scene, simulate
from wearbench.model.surfaces import JointSurfaces
from wearbench.model.wear_stages import StagePlan, run_stages

from .conftest import disc_bench

SPEED = -5 * math.pi
CLEAR = {"A": 0.6e-3, "B": 0.6e-3}


@pytest.fixture(scope="module")
def bench():
    return load_bench(shipped_bench("ninebar"))


def test_unworn_surfaces_reproduce_even_clearance_exactly(bench):
    """New surfaces (all depths zero) take the even-clearance path: bit-identical tables and
    contact records, step for step."""
    zero = {j: JointSurfaces.unworn(1000) for j in CLEAR}
    plain = simulate(build_scene(bench, clearances=CLEAR, surfaces={}), revolutions=0.5, speed=SPEED,
                     record_contacts=True)
    worn0 = simulate(build_scene(bench, clearances=CLEAR, surfaces=zero), revolutions=0.5, speed=SPEED,
                     record_contacts=True)
    assert plain.summary["steps"] == worn0.summary["steps"]
    pd.testing.assert_frame_equal(plain.table, worn0.table, check_exact=True)
    for j in CLEAR:
        pd.testing.assert_frame_equal(plain.contacts[j], worn0.contacts[j], check_exact=True)


def test_circular_journal_rests_on_the_rims_of_a_narrow_pit(bench):
    """A bearing pit 3 deg wide and 100 um deep: the contact search finds the overlap on its rims,
    as a brute-force maximum over 20,000 directions does; the old along-the-line-of-centres lookup
    would have let the journal sink 100 um into it."""
    from wearbench.model.worn_contact import worn_contact

    n, c = 1000, 0.6e-3
    pit = np.zeros(n)
    pit[495:505] = 100e-6 * np.hanning(12)[1:-1]
    centre = 2 * np.pi * 500 / n
    phi = np.linspace(centre - 0.5, centre + 0.5, 20_001)
    from wearbench.model.surface_tables import depth_at

    for emag, alpha in ((c + 5e-6, centre), (c + 20e-6, centre + 0.004), (c + 2e-6, centre - 0.02)):
        _, f, hb, _, _, _ = worn_contact(pit, n, np.zeros(n), n, emag, alpha, 0.0, 0.3, c)
        brute = (emag * np.cos(phi - alpha) - depth_at(pit, phi)).max()
        assert brute - 1e-12 <= f <= brute + 2e-9  # a true maximum, at least every grid sample
        assert hb < 0.05 * pit.max()  # on a rim, not in the pit
        assert f - c < emag - c  # less penetration than a circle without the pit would have


def _rims(n=1000):
    """A bearing pit 3 deg wide and 100 um deep around region 500, and its centre (rad)."""
    pit = np.zeros(n)
    pit[495:505] = 100e-6 * np.hanning(12)[1:-1]
    return pit, 2 * np.pi * 500 / n


def test_second_zone_is_the_other_rim_of_a_bridged_pit():
    """A journal bridging a narrow pit touches both rims: the second zone is the other local
    maximum of the overlap, with the saddle between them, as a brute-force grid finds them."""
    from wearbench.model.surface_tables import depth_at
    from wearbench.model.worn_contact import second_zone, worn_contact

    pit, centre = _rims()
    n, c = pit.size, 0.6e-3
    phi = np.linspace(centre - 0.5, centre + 0.5, 200_001)
    for emag, alpha in ((c + 5e-6, centre + 1e-4), (c + 20e-6, centre - 0.002)):
        psi1, f1, *_ = worn_contact(pit, n, np.zeros(n), n, emag, alpha, 0.0, 0.3, c)
        psi2, f2, sad = second_zone(pit, n, np.zeros(n), n, emag, alpha, 0.0, 0.3, c, psi1, f1)
        f = emag * np.cos(phi - alpha) - depth_at(pit, phi)
        peaks = np.flatnonzero((f[1:-1] > f[:-2]) & (f[1:-1] >= f[2:])) + 1
        top2 = peaks[np.argsort(f[peaks])[-2:]]
        assert sorted([psi1, psi2]) == pytest.approx(sorted(phi[top2]), abs=1e-3)  # flat tops
        assert f2 == pytest.approx(f[top2].min(), abs=1e-10) and f2 <= f1
        lo, hi = sorted(top2)
        # the saddle is sampled at interval midpoints: never below the true one, here below the
        # clearance as the true one is (the journal does not touch the pit's bottom)
        assert f[lo:hi + 1].min() <= sad < c
        assert (psi1 - centre) * (psi2 - centre) < 0  # one on each rim


def test_two_zone_force_is_continuous_when_the_zones_trade_places():
    """Sweeping the journal across the pit centre, the two rims trade places as the top zone.
    One force at the top zone jumps by the rims' angle there; the two-zone force (each rim its
    own normal, shared levels split) changes by no more than its smooth neighbours do."""
    from wearbench.model.worn_contact import second_zone, worn_contact, zone_penetrations

    pit, centre = _rims()
    n, c = pit.size, 0.6e-3
    emag = c + 10e-6
    one, two = [], []
    for alpha in centre + np.linspace(-2e-3, 2e-3, 401):
        psi1, f1, *_ = worn_contact(pit, n, np.zeros(n), n, emag, alpha, 0.0, 0.3, c)
        psi2, f2, sad = second_zone(pit, n, np.zeros(n), n, emag, alpha, 0.0, 0.3, c, psi1, f1)
        u1, u2 = np.array([np.cos(psi1), np.sin(psi1)]), np.array([np.cos(psi2), np.sin(psi2)])
        one.append((f1 - c) ** 1.5 * u1)
        if np.isfinite(f2):
            p1, p2, r = zone_penetrations(f1, f2, sad, c)
            two.append(p1 ** 1.5 * u1 + r * p2 ** 1.5 * u2)
        else:
            two.append(one[-1])
    one, two = np.array(one), np.array(two)
    jump_one = np.linalg.norm(np.diff(one, axis=0), axis=1).max()
    jump_two = np.linalg.norm(np.diff(two, axis=0), axis=1).max()
    assert jump_one > 0.03 * np.linalg.norm(one, axis=1).max()  # the rims are 3 deg apart
    assert jump_two < 0.002 * np.linalg.norm(two, axis=1).max()


def test_zone_penetrations_are_continuous_at_merge_swap_and_fade():
    from wearbench.model.worn_contact import zone_penetrations

    c = 0.6e-3
    f1 = c + 4e-6
    # merge: the second peak sinks into the saddle, the first takes the whole overlap
    p1, p2, _ = zone_penetrations(f1, c + 3e-6, c + 3e-6, c)
    assert p2 == 0.0 and p1 == pytest.approx(4e-6, abs=1e-18)
    # swap: equal peaks share equally
    p1, p2, r = zone_penetrations(f1, f1, c + 1e-6, c)
    assert p1 == pytest.approx(p2, abs=1e-18) and r == 1.0
    assert p1 + p2 == pytest.approx(2 * 3e-6 + 1e-6, abs=1e-18)  # own heights + the shared level
    # fade: at half the first's overlap the second zone has no weight and the first has it all
    p1, p2, r = zone_penetrations(f1, c + 2e-6, c + 1e-6, c)
    assert r == pytest.approx(0.0, abs=1e-12) and p1 == pytest.approx(4e-6, abs=1e-17)
    # separate zones (saddle below the clearance): each its own overlap
    p1, p2, r = zone_penetrations(f1, c + 3.5e-6, c - 1e-6, c)
    assert (p1, p2) == pytest.approx((4e-6, 3.5e-6), abs=1e-18) and 0.0 < r < 1.0


def test_sharp_steps_neither_stall_nor_explode(bench):
    # 40 um deep pockets with vertical walls every 10 regions on both surfaces of both joints
    step = np.where((np.arange(1000) // 10) % 2 == 0, 40e-6, 0.0)
    rough = {j: JointSurfaces(step, step[::-1].copy(), 0, "steps") for j in CLEAR}
    smooth = simulate(build_scene(bench, clearances=CLEAR, surfaces={}), revolutions=1, speed=SPEED)
    res = simulate(build_scene(bench, clearances=CLEAR, surfaces=rough), revolutions=1, speed=SPEED)
    t = res.table
    assert t["t"].iloc[-1] == pytest.approx(2 * math.pi / abs(SPEED), rel=1e-6)
    assert np.isfinite(t.select_dtypes("number").to_numpy()).all()
    # journal stays near its bearing: radial penetration stays a fraction of the clearance (a
    # blow-up would run through it); it exceeds the smooth case's because it is measured radially
    # into the pocket walls
    for j, c in CLEAR.items():
        assert t[f"{j}_pen"].max() < 0.25 * c
    # bounded work: not more than 20x the steps of the smooth surfaces
    assert res.summary["steps"] < 20 * smooth.summary["steps"]


@pytest.mark.slow
def test_simulated_stage_conserves_archard_volume_and_wears_contact_zones(bench):
    plan = StagePlan.from_bench(bench, stages=1, min_updates=2)
    run = run_stages(bench, plan, clearances=CLEAR, speed=SPEED)
    stage = run.stages[0]
    for j in CLEAR:
        s = stage.surfaces[j]
        assert s.cycles == plan.stage_cycles and s.label == "first wear"
        assert s.bearing.max() > 0 and s.journal.max() > 0
        assert stage.volume[j] == pytest.approx(stage.archard_volume[j], rel=1e-9)


@pytest.mark.slow
def test_wear_command_writes_surfaces_summary_and_plots(tmp_path):
    out = tmp_path / "wear"
    code = main(["wear", str(shipped_bench("ninebar")), "--clearance", "0.6mm", "--speed", "-5pi", "--stages", "2",
                 "--stage-cycles", "2000", "--convergence", "1,2", "--out", str(out)])
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    conv = pd.read_csv(out / "convergence.csv")
    # refinement holds the total cycle count: both runs wear 2 x 2000 cycles, the finer in twice the updates
    assert sorted(set(conv["refinement"])) == [1, 2] and set(conv["total_cycles"]) == {4000}
    ups = conv.groupby("refinement")["updates"].first()
    assert ups[2] == 2 * ups[1] == 32  # 8 updates per stage at least, times the refinement
    assert {"bearing_reachable_m", "journal_reachable_m", "volume_m3", "volume_change"} <= set(conv.columns)
    assert [s["label"] for s in summary["stages"]] == ["first wear", "second wear"]
    a1 = summary["stages"][0]["joints"]["A"]["bearing"]["max_depth_m"]
    a2 = summary["stages"][1]["joints"]["A"]["bearing"]["max_depth_m"]
    assert 0 < a1 < a2
    second = JointSurfaces.load(out / "surfaces" / "B_2.npz")
    assert second.label == "second wear" and second.cycles == 4000
    assert (out / "depths.csv").exists() and (out / "wear_depth.png").exists() and (out / "surface_A.png").exists()


def test_wear_command_bad_clearance_is_one_line(tmp_path, capsys):
    code = main(["wear", str(shipped_bench("ninebar")), "--clearance", "Z=0.6mm", "--out", str(tmp_path)])
    assert code == 2
    assert "no clearance joint 'Z'" in capsys.readouterr().err


def test_journal_spinning_on_its_bearing_under_gravity_wears_as_closed_form_archard():
    """A 1 kg journal resting on the bottom of a fixed bearing, spinning at omega without friction:
    the contact stays at the bearing's 270 deg with F = m g, so Archard gives bearing depth
    split K_n P(mg) R1 omega t, and the journal wears evenly over whole revolutions."""
    from wearbench.model.wear import WearLaw, accumulate_wear, worn_volume

    bench = disc_bench(g=-9.81, ce=0.9, cf=0.0)
    scene = build_scene(bench, surfaces={})
    omega, t_end, mg = 8 * math.pi, 0.5, 9.81  # two whole revolutions
    law = WearLaw.from_bench(bench, "J", footprint="hertz")  # its even footprint has a closed-form peak
    k = 4 / (3 * 2 * (1 - 0.3**2) / 206e9) * math.sqrt(0.015 * 0.0145 / 0.0005)  # conformal stiffness
    q0 = scene.q0.copy()
    q0[0:3] = (0.0, -(0.5e-3 + (mg / k) ** (1 / 1.5)), 0.0)  # statically seated at the bottom
    v0 = np.zeros_like(scene.v0)
    v0[2] = omega
    res = simulate(scene, t_end=t_end, initial=(q0, v0), record_contacts=True)
    rec = res.contacts["J"]
    assert rec["fn"].iloc[len(rec) // 2:].mean() == pytest.approx(mg, rel=1e-3)
    s = accumulate_wear(rec, law, 4000)
    h = law.coefficient * law.pressure(mg) * law.bearing_radius * omega * t_end  # eq. 17 at constant P
    assert s.bearing.max() == pytest.approx(law.split * h, rel=2e-3)
    assert (np.argmax(s.bearing) + 0.5) * 360 / 4000 == pytest.approx(270.0, abs=0.5)
    assert worn_volume(s, law) == pytest.approx(law.coefficient * mg * law.bearing_radius * omega * t_end, rel=0.01)
    journal = s.journal[s.journal > 0]
    assert journal.size > 3900 and journal.std() < 0.02 * journal.mean()  # even all round
