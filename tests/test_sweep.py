"""`wearbench sweep`: axis parsing, a small sweep on a 2-worker LocalCluster equal to the same runs in
this process, failures named with their parameters, the CLI's files."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest
from hypothesis import given
from hypothesis import strategies as st
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.cli import main
from wearbench.studies.sweep import Axis, SweepSpec, parse_axis, run_point, run_sweep


def test_parse_axis_ranges_and_lists_in_si():
    a = parse_axis("clearance=0.1mm..0.6mm:6")
    assert a.name == "clearance"
    np.testing.assert_allclose(a.values, [1e-4, 2e-4, 3e-4, 4e-4, 5e-4, 6e-4], rtol=1e-12)
    s = parse_axis("speed=-6pi..-4pi:5")
    np.testing.assert_allclose(s.values, [-6 * math.pi, -5.5 * math.pi, -5 * math.pi, -4.5 * math.pi, -4 * math.pi])
    assert parse_axis("speed=300rpm,-5pi").values == pytest.approx((10 * math.pi, -5 * math.pi))
    assert parse_axis("clearance.B=0.2mm").values == pytest.approx((2e-4,))
    for text, match in [("clearance", "expected NAME=FROM..TO:COUNT"), ("gap=1mm", "unknown parameter 'gap'"),
                        ("clearance=0.1mm..0.6mm", "needs a count"), ("clearance=0.1mm..0.6mm:0", "count '0'"),
                        ("clearance=0.1..0.6mm:3", "has no unit"), ("speed=1mm,2mm", "not a angular_speed unit"),
                        ("clearance=1mm,1mm", "values repeat")]:
        with pytest.raises(ValueError, match=match):
            parse_axis(text)


@given(lo=st.floats(0.01, 1.0), span=st.floats(0.01, 1.0), n=st.integers(2, 12))
def test_a_range_has_its_count_and_both_ends(lo, span, n):
    a = parse_axis(f"clearance={lo!r}mm..{lo + span!r}mm:{n}")
    assert len(a.values) == n
    assert a.values[0] == pytest.approx(lo * 1e-3) and a.values[-1] == pytest.approx((lo + span) * 1e-3)
    assert np.all(np.diff(a.values) > 0)


@pytest.fixture(scope="module")
def bench():
    return load_bench(shipped_bench("slider-crank"))


def _spec(*axes: Axis, **kw) -> SweepSpec:
    return SweepSpec(axes=axes, revolutions=0.5, settle=0.25, output_rate=2_000.0, **kw)


def test_sweep_on_two_workers_equals_the_same_runs_in_process(bench):
    spec = _spec(Axis("clearance", (0.2e-3, 0.4e-3)), Axis("speed", (-400.0, -500.0)), realisations=2, seed=3)
    res = run_sweep(bench, spec, workers=2, cache=False)
    assert not res.failures
    df = res.table
    assert df["run"].nunique() == 8 and set(df["seed"]) == {3, 4}
    # one row per run, state and statistic: 2 slider statistics + peak force at the one clearance joint
    assert set(df["statistic"]) == {"peak_slider_acc", "rms_slider_acc", "peak_fn_S"}
    assert len(df) == 8 * 3 and not df.duplicated(["run", "state", "statistic"]).any()
    # the same run computed here, serially, without the cluster
    row = df[(df["clearance_m"] == 0.4e-3) & (df["speed_rad_s"] == -500.0) & (df["seed"] == 4)]
    direct = pd.DataFrame(run_point(bench, {"clearance": 0.4e-3, "speed": -500.0}, 4, spec))
    np.testing.assert_allclose(row.sort_values("statistic")["value"].to_numpy(),
                               direct.sort_values("statistic")["value"].to_numpy(), rtol=1e-12)
    # realisations differ from each other (drawn within the bench's tolerances)
    peaks = df[(df["statistic"] == "rms_slider_acc") & (df["clearance_m"] == 0.2e-3)
               & (df["speed_rad_s"] == -400.0)]["value"]
    assert peaks.nunique() == 2


def test_a_failed_run_is_named_with_its_parameters_and_hides_nothing(bench):
    bearing = bench.clearance_joints[0].clearance.bearing_radius
    spec = _spec(Axis("clearance", (0.2e-3, 2 * bearing)))
    res = run_sweep(bench, spec, workers=0)
    assert set(res.table["clearance_m"]) == {0.2e-3}
    (run, failure), = res.failures
    assert run["clearance_m"] == 2 * bearing
    assert f"clearance={2 * bearing * 1e3:.4g}mm" in failure.label
    assert failure.params["values"] == {"clearance": 2 * bearing}
    assert "clearance S" in failure.error and "bearing radius" in failure.error
    assert res.failures_table()["clearance_m"].tolist() == [2 * bearing]


def test_cli_writes_parquet_plots_and_failures(tmp_path, capsys, monkeypatch):
    from wearbench.studies import sweep

    out = tmp_path / "sweep"
    args = ["sweep", str(shipped_bench("slider-crank")), "--vary", "clearance=0.2mm,20mm", "--vary", "speed=-4000rpm",
            "--dyn-revolutions", "0.5", "--dyn-settle", "0.25", "--output-rate", "2000", "--workers", "0",
            "--out", str(out)]
    assert main(args) == 2  # a clearance beyond the bearing is refused before any run
    assert "--vary clearance '20mm'" in capsys.readouterr().err and not out.exists()
    real = sweep.run_point

    def fails_at_half_a_millimetre(bench, values, seed, spec):
        if values["clearance"] > 0.4e-3:
            raise ValueError("contact at S: penetration beyond the bearing radius")
        return real(bench, values, seed, spec)

    monkeypatch.setattr(sweep, "run_point", fails_at_half_a_millimetre)
    args[3] = "clearance=0.2mm,0.5mm"
    rc = main(args)
    assert rc == 1  # one run failed; the rest is written
    err = capsys.readouterr().err
    assert "failed: clearance=0.5mm speed=-418.9rad/s" in err and "bearing radius" in err
    df = pd.read_parquet(out / "sweep.parquet")
    assert list(df.columns) == ["run", "clearance_m", "speed_rad_s", "realisation", "seed", "state", "statistic",
                                "value", "unit"]
    assert set(df["run"]) == {0}
    assert pd.read_csv(out / "failures.csv")["clearance_m"].tolist() == [0.0005]
    summary = json.loads((out / "sweep.json").read_text())
    assert summary["runs"] == 2 and summary["failed"] == 1
    assert {p.name for p in (out / "plots").glob("*.png")} == {"peak_slider_acc.png", "rms_slider_acc.png",
                                                               "peak_fn_S.png"}
    assert main(["sweep", str(shipped_bench("slider-crank")), "--vary", "clearance.Q=1mm", "--out",
                 str(out)]) == 2
    assert "no clearance joint 'Q'" in capsys.readouterr().err


def test_commands_on_a_bench_use_its_compute_scheduler_unless_told_otherwise(tmp_path, monkeypatch, capsys):
    from wearbench.model import wear_stages
    from wearbench.studies import sweep

    bench = tmp_path / "bench.toml"
    bench.write_text(shipped_bench("slider-crank").read_text() + '\n[compute]\nscheduler = "tcp://127.0.0.1:8791"\n')
    seen = []

    def fake_run_sweep(bench, spec, **kwargs):
        seen.append(kwargs["scheduler"])
        raise RuntimeError("stop here")

    monkeypatch.setattr(sweep, "run_sweep", fake_run_sweep)
    args = ["sweep", str(bench), "--vary", "clearance=0.2mm", "--out", str(tmp_path / "out")]
    monkeypatch.delenv("WEARBENCH_SCHEDULER", raising=False)
    assert main(args) == 2
    monkeypatch.setenv("WEARBENCH_SCHEDULER", "tcp://127.0.0.1:9000")
    assert main(args) == 2
    assert main([*args, "--scheduler", "local"]) == 2
    assert seen == ["tcp://127.0.0.1:8791", "tcp://127.0.0.1:9000", "local"]

    # wear --convergence takes the same options and rejects a bad one before the (long) wear run
    monkeypatch.setattr(wear_stages, "run_stages", lambda *a, **k: pytest.fail("ran despite a bad --scheduler"))
    capsys.readouterr()
    assert main(["wear", str(bench), "--convergence", "1,2", "--scheduler", "10.0.0.5", "--workers", "2",
                 "--out", str(tmp_path / "wear")]) == 2
    assert "scheduler = '10.0.0.5': expected 'local' or a Dask scheduler address" in capsys.readouterr().err


def test_overlapping_axes_follow_one_rule_and_the_cache_keys_the_computation(bench):
    """Issue 25, item 5: `--vary clearance.A=0.2mm,0.5mm --vary clearance=0.3mm` gave two identical
    rows computed at 0.3 mm, and in the other order an answer that depended on what ran before (the
    cache keyed the request, sorted, while applying it depended on the order). The joint's own axis
    sets that joint in either order, and the cache key is the applied parameters."""
    joint = Axis("clearance.S", (0.2e-3, 0.5e-3))
    every = Axis("clearance", (0.3e-3,))

    def values(*axes):
        df = run_sweep(bench, _spec(*axes), workers=0).table
        peaks = df[df["statistic"] == "rms_slider_acc"]
        return {c: peaks[peaks["clearance_S_m"] == c]["value"].item() for c in joint.values}

    first = values(joint, every)  # cold cache
    second = values(every, joint)  # the other order: served from the cache only where the computation is equal
    alone = values(joint)  # the same clearances without the overlapping axis: the same computation
    assert first == second == alone
    assert first[0.2e-3] != first[0.5e-3]
    direct = pd.DataFrame(run_point(bench, {"clearance.S": 0.5e-3}, None, _spec(joint)))
    assert direct[direct["statistic"] == "rms_slider_acc"]["value"].item() == first[0.5e-3]


def test_a_change_of_the_studies_code_changes_the_task_keys(bench, monkeypatch):
    """The sweep left ``model/`` (whose source digest every task key holds): its keys hold the
    digest of the functions its tasks run, so a changed sweep never replays a cached result of the
    old code."""
    from wearbench.studies import sweep

    keys = []

    def capture(tasks, **_):
        keys.append([t.key for t in tasks])
        raise KeyboardInterrupt  # the keys are all this test needs

    monkeypatch.setattr(sweep, "run_tasks", capture)
    spec = _spec(Axis("clearance.S", (0.2e-3,)))
    for digest in (sweep.tasks_source_digest(sweep.run_point, sweep._apply), "changed"):
        monkeypatch.setattr(sweep, "tasks_source_digest", lambda *_, d=digest: d)
        with pytest.raises(KeyboardInterrupt):
            run_sweep(bench, spec, workers=0)
    assert len(keys[0]) == len(keys[1]) == 1 and keys[0] != keys[1]
