"""Wear-stage bookkeeping (model/wear_stages.py) on a stand-in simulator with a known contact record,
so scaling, settling, labels, zones and convergence are checked against closed forms."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
from wearbench import model
from wearbench.hardware.bench import load_bench, shipped_bench
from wearbench.model.wear import WearLaw
from wearbench.model.wear_report import load_states, run_summary, write_run
from wearbench.model.wear_stages import StagePlan, convergence, run_stages, stage_label, wear_zones

FN, OMEGA = 600.0, 3.0  # N, rad/s: steady load, journal turning relative to the bearing
DT = 2e-4


@pytest.fixture
def fake_model(monkeypatch):
    """build_scene/simulate stand-ins: contact at bearing angle 1 rad with FN while the journal turns."""
    calls = []

    def build_scene(bench, *, clearances=None, surfaces=None):
        calls.append({j: s.cycles for j, s in (surfaces or {}).items()})
        return SimpleNamespace(bench=bench)

    def simulate(scene, *, revolutions, speed, method="default", record_contacts=False, **kw):
        t_end = revolutions * 2 * math.pi / abs(speed)
        t = np.arange(round(t_end / DT)) * DT
        rec = pd.DataFrame({"t": t, "dt": DT, "fn": FN, "vt": 0.0, "omega_rel": OMEGA, "phi_bearing": 1.0,
                            "phi_journal": np.mod(1.0 - OMEGA * t, 2 * np.pi), "pen": 1e-6})
        contacts = {j.name: rec for j in scene.bench.clearance_joints} if record_contacts else None
        return SimpleNamespace(contacts=contacts, table=None,
                               summary={"method": method, "steps": t.size, "peak_fn": {}, "peak_slider_acc": 0.0})

    monkeypatch.setattr(model, "build_scene", build_scene, raising=False)
    monkeypatch.setattr(model, "simulate", simulate, raising=False)
    return calls


@pytest.fixture(scope="module")
def bench():
    return load_bench(shipped_bench("ninebar"))


def test_stages_scale_settle_and_accumulate(fake_model, bench):
    speed = -5 * math.pi
    plan = StagePlan(stages=2, stage_cycles=1000.0, sim_cycles=2.0, settle=1.0)
    run = run_stages(bench, plan, speed=speed)
    law = WearLaw.from_bench(bench, "A")
    counted = 2.0 * 2 * math.pi / abs(speed)  # s: settle revolution excluded
    h = law.coefficient * law.pressure(FN) * law.bearing_radius * OMEGA * counted * (1000.0 / 2.0)
    first, second = run.stages
    assert [s.label for s in run.stages] == ["first wear", "second wear"]
    assert first.surfaces["A"].bearing.max() == pytest.approx(0.5 * h, rel=2e-3)
    assert second.surfaces["A"].bearing.max() == pytest.approx(h, rel=2e-3)
    assert second.surfaces["B"].cycles == 2000.0
    # each stage was simulated on the surfaces before it
    assert fake_model == [{"A": 0.0, "B": 0.0}, {"A": 1000.0, "B": 1000.0}]
    # worn volume equals the Archard volume of the counted steps, scaled
    assert first.volume["A"] == pytest.approx(first.archard_volume["A"], rel=1e-6)
    summary = run_summary(run)
    zones = summary["stages"][0]["joints"]["A"]["bearing"]["zones_deg"]
    assert len(zones) == 1 and zones[0][0] <= math.degrees(1.0) <= zones[0][1]


def test_write_and_read_back(fake_model, bench, tmp_path):
    run = run_stages(bench, StagePlan(stages=1, stage_cycles=10.0, sim_cycles=1.0), speed=-5 * math.pi)
    paths = write_run(run, tmp_path, plots=True)
    states = load_states(tmp_path)
    np.testing.assert_array_equal(states["A"][1].bearing, run.final["A"].bearing)
    csv = pd.read_csv(paths["csv"])
    assert set(csv["joint"]) == {"A", "B"} and len(csv) == 4 * 1000
    assert paths["depth_plot"].stat().st_size > 0 and paths["polar_B"].exists()


def test_finer_stages_converge_to_same_total_for_steady_load(fake_model, bench):
    # with a wear-independent load, any staging gives the same final depth: convergence is exact
    runs = {k: run_stages(bench, StagePlan(stages=k, stage_cycles=4000.0 / k, sim_cycles=1.0), speed=-5 * math.pi)
            for k in (1, 2, 4)}
    rows = convergence(runs)
    assert all(r["bearing_rms_diff_rel"] < 1e-9 for r in rows)
    assert {r["total_cycles"] for r in rows} == {4000.0}


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
    with pytest.raises(ValueError, match="simulated cycles"):
        StagePlan(sim_cycles=0)
