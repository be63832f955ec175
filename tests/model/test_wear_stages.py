"""Wear-stage bookkeeping (model/wear_stages.py) on a stand-in simulator with a known contact record,
so update sizes, continuation, cycle counts, labels, zones and convergence are checked against
closed forms."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
import wearbench.model
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.model.wear import WearLaw
from wearbench.model.wear_stages import StagePlan, convergence, run_stages, stage_label, wear_zones
from wearbench.studies.wear_report import load_states, run_summary, write_run

FN, OMEGA = 600.0, 3.0  # N, rad/s: steady load, journal turning relative to the bearing
DT = 2e-4


@pytest.fixture
def fake_model(monkeypatch):
    """build_scene/simulate stand-ins: contact at bearing angle 1 rad with FN while the journal turns;
    every simulation ends where it started, so the run continues without settling again."""
    calls = []

    def build_scene(bench, *, clearances=None, surfaces=None):
        calls.append({j: s.cycles for j, s in (surfaces or {}).items()})
        return SimpleNamespace(bench=bench, q0=np.zeros(3))

    def simulate(scene, *, revolutions, speed, method="default", record_contacts=False, initial=None, **kw):
        calls[-1]["revolutions"] = revolutions
        calls[-1]["continued"] = initial is not None
        period = 2 * math.pi / abs(speed)  # every revolution the same: a steady periodic load
        t_end = revolutions * period
        t = np.arange(round(t_end / DT)) * DT
        rec = pd.DataFrame({"t": t, "dt": DT, "fn": FN, "vt": 0.0, "omega_rel": OMEGA, "phi_bearing": 1.0,
                            "phi_journal": np.mod(1.0 - OMEGA * np.mod(t, period), 2 * np.pi), "pen": 1e-6})
        contacts = {j.name: rec for j in scene.bench.clearance_joints} if record_contacts else None
        return SimpleNamespace(contacts=contacts, table=None, final=(np.zeros(3), np.zeros(3)),
                               summary={"method": method, "steps": t.size, "peak_fn": {}, "peak_slider_acc": 0.0})

    monkeypatch.setattr(wearbench.model, "build_scene", build_scene, raising=False)
    monkeypatch.setattr(wearbench.model, "simulate", simulate, raising=False)
    return calls


@pytest.fixture(scope="module")
def bench():
    return load_bench(shipped_bench("ninebar"))


def _per_cycle_depth(bench, speed):
    """Bearing depth per crank cycle at the steady load (Hertz footprint: closed form, eq. 17)."""
    law = WearLaw.from_bench(bench, "A")
    return law.split * law.coefficient * law.pressure(FN) * law.bearing_radius * OMEGA * 2 * math.pi / abs(speed)


def test_updates_cap_the_depth_and_the_stages_hold_their_cycles(fake_model, bench):
    speed = -5 * math.pi
    per_cycle = _per_cycle_depth(bench, speed)
    cap = 250 * per_cycle  # 1000 cycles per stage -> 4 updates of 250 cycles each
    plan = StagePlan(stages=2, stage_cycles=1000.0, update_depth=cap, settle=1, footprint="hertz", min_updates=1)
    run = run_stages(bench, plan, speed=speed)
    first, second = run.stages
    assert [s.label for s in run.stages] == ["first wear", "second wear"]
    assert first.surfaces["A"].bearing.max() == pytest.approx(1000 * per_cycle, rel=2e-3)
    assert second.surfaces["A"].bearing.max() == pytest.approx(2000 * per_cycle, rel=2e-3)
    assert second.surfaces["B"].cycles == 2000.0 and first.surfaces["A"].cycles == 1000.0
    assert (first.updates, second.updates) == (4, 4)
    # one continuous run: a settling revolution before the first update only; cost = revolutions
    assert [c["revolutions"] for c in fake_model] == [2] + [1] * 7
    assert [c["continued"] for c in fake_model] == [False] + [True] * 7
    assert run.revolutions == 9
    # every update is simulated on the surfaces the previous one left
    assert [c["A"] for c in fake_model] == pytest.approx([0, 250, 500, 750, 1000, 1250, 1500, 1750])
    # worn volume equals the Archard volume of the cycles represented
    assert first.volume["A"] == pytest.approx(first.archard_volume["A"], rel=1e-6)
    summary = run_summary(run)
    zones = summary["stages"][0]["joints"]["A"]["bearing"]["zones_deg"]
    assert len(zones) == 1 and zones[0][0] <= math.degrees(1.0) <= zones[0][1]


def test_write_and_read_back(fake_model, bench, tmp_path):
    run = run_stages(bench, StagePlan(stages=1, stage_cycles=10.0), speed=-5 * math.pi)
    paths = write_run(run, tmp_path, plots=True)
    states = load_states(tmp_path)
    np.testing.assert_array_equal(states["A"][1].bearing, run.final["A"].bearing)
    csv = pd.read_csv(paths["csv"])
    assert set(csv["joint"]) == {"A", "B"} and len(csv) == 4 * 1000
    assert paths["depth_plot"].stat().st_size > 0 and paths["polar_B"].exists()


def test_refinement_at_fixed_cycles_converges_exactly_for_steady_load(fake_model, bench):
    # with a wear-independent load the update size does not matter: same totals, zero change
    speed = -5 * math.pi
    cap = 300 * _per_cycle_depth(bench, speed)
    runs = {k: run_stages(bench, StagePlan(stages=2, stage_cycles=2000.0, update_depth=cap, refinement=k,
                                           footprint="hertz", min_updates=1), speed=speed) for k in (1, 2, 4)}
    rows = convergence(runs)
    assert {r["total_cycles"] for r in rows} == {4000.0}
    assert [r["updates"] for r in rows if r["joint"] == "A"] == [14, 28, 54]  # ceil(2000 / (300 / k)) per stage
    changes = [v for r in rows for k, v in r.items() if k.endswith("_change") and not math.isnan(v)]
    assert changes and max(changes) < 1e-9
    # the Hertz footprint at a fixed bearing angle digs a pit ~4 deg wide and ~70 um deep: a circular
    # counter-body with 0.6 mm clearance needs ~sqrt(2 h / c) = 28 deg to reach its bottom
    a = rows[-1]
    assert a["bearing_max_m"] > 5e-5 and a["bearing_reachable_m"] < 0.05 * a["bearing_max_m"]


def test_zones_and_labels():
    d = np.zeros(360)
    d[0:20] = 1.0
    d[350:] = 1.0
    d[100:150] = 2.0
    assert wear_zones(d) == [(0.0, 20.0), (100.0, 150.0), (350.0, 360.0)]
    assert wear_zones(np.zeros(10)) == []
    assert stage_label(2) == "second wear" and stage_label(11) == "wear stage 11"


def test_bad_plans():
    with pytest.raises(ValueError, match="stages = 0"):
        StagePlan(stages=0)
    with pytest.raises(ValueError, match="update depth"):
        StagePlan(update_depth=0)
    with pytest.raises(ValueError, match="revolutions per update = 0.5"):
        StagePlan(update_revolutions=0.5)
