"""End to end: sessions recorded from the bench emulator (known truth) through the real acquisition
recorder, read back from MCAP, scored against simulated theory, and the `wearbench compare` CLI."""

import json
import math
import re

import pytest
from wearbench.acquisition.backends import open_rig
from wearbench.acquisition.recorder import record_session
from wearbench.acquisition.session import SessionPlan
from wearbench.bench.load import load_bench, parse_bench, shipped_bench
from wearbench.cli import main
from wearbench.hardware.emulators.device import table_speed
from wearbench.validation import CompareOptions, rank_theories
from wearbench.validation.comparison.theory import simulate_theory

pytestmark = pytest.mark.slow  # records and simulates: ~30 s with cold numba caches

DELAY = 0.5e-3  # s: the accelerometer signal lags the crank by this much (emulator truth)
EMULATOR = {"truth": {"accel_delay": "0.5 ms"}, "accelerometer": {"noise": "0.2 m/s^2", "bias": "0.3 m/s^2"}}


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """Two 7-cycle sessions of the nine-bar test bed: ideal joints, and 0.3 mm clearance at A and B."""
    out = tmp_path_factory.mktemp("sessions")
    mp = pytest.MonkeyPatch()
    mp.setenv("WEARBENCH_CACHE", str(out / "cache"))  # emulator tables from the current model
    path = shipped_bench("ninebar-testbed")
    clearance = load_bench(path)
    text = re.sub(r"\n\[\[state\]\].*", "\n", path.read_text(), flags=re.DOTALL)  # states name clearances
    ideal = parse_bench(re.sub(r"\[joint\.clearance\].*?(?=\n\[\[|\n\[[a-z])", "", text, flags=re.DOTALL),
                        "ninebar-testbed-ideal")
    assert not ideal.clearance_joints and len(clearance.clearance_joints) == 2
    files = {}
    for name, bench in (("ideal", ideal), ("0.3mm", clearance)):
        files[name] = out / f"{name}.mcap"
        rig = open_rig(bench, "sim", {"speedup": math.inf, "config": EMULATOR})
        record_session(rig, bench, SessionPlan(speed=bench.speed, cycles=7), files[name])
    # a twin (plumbing) check: the emulator plays the nominal model's settled revolution at the speed
    # of its table, so the theories are simulated at that speed; non-twin identification is tested in
    # test_identify_nontwin.py
    speed = table_speed(clearance.speed)
    theories = {"ideal": simulate_theory(ideal, speed=speed, revolutions=2),
                "0.3mm": simulate_theory(clearance, speed=speed, revolutions=3)}
    yield files, theories
    mp.undo()


def test_matching_theory_scores_higher(recorded):
    files, theories = recorded
    for truth, path in files.items():
        ranking = rank_theories(path, theories, options=CompareOptions())
        assert ranking[0].label == truth, [(r.label, r.rating) for r in ranking]
        assert ranking[0].rating > ranking[1].rating + 0.02


def test_sensor_delay_recovered_from_a_recording(recorded):
    files, theories = recorded
    best = rank_theories(files["ideal"], {"ideal": theories["ideal"]})[0]
    for w in best.comparison.windows:
        assert w.shift_s == pytest.approx(-DELAY, abs=0.2e-4)  # theory early by the delay: 0.2 samples
        assert w.scores.correlation > 0.999
    assert best.rating > 0.85  # slope score limited by the sensor noise


def test_compare_cli(recorded, tmp_path, capsys):
    files, theories = recorded
    run = tmp_path / "theory.parquet"
    theories["0.3mm"].to_parquet(run)
    out = tmp_path / "report"
    code = main(["compare", str(files["ideal"]), str(files["0.3mm"]), "--out", str(out),
                 "--theory", str(run), "--filter", "cfc600", "--windows", "random:1:3"])
    assert code == 0
    for name in ("report.html", "scores.json", "sessions_measured.png", "sessions_comparison.png",
                 "overlay_ideal.png", "spectrum_0.3mm.png"):
        assert (out / name).is_file(), name
    scores = json.loads((out / "scores.json").read_text())
    assert [s["label"] for s in scores["sessions"]] == ["ideal", "0.3mm"]
    assert scores["options"]["filter"] == "SAE J211 CFC 600"
    assert all(len(s["windows"]) == 1 for s in scores["sessions"])
    assert "ISO R" in capsys.readouterr().out
    # errors meant for the user: one line, exit 2
    assert main(["compare", str(files["ideal"]), "--out", str(out), "--filter", "cfc100"]) == 2
    assert main(["compare", str(tmp_path / "missing.mcap"), "--out", str(tmp_path / "report2")]) == 2


def test_compare_scores_what_it_can_and_says_what_is_unfinished(recorded, tmp_path, capsys):
    """A session too short to score does not cost the others; a file cut short is scored and called
    unfinished in the output and the report."""
    files, theories = recorded
    run = tmp_path / "theory.parquet"
    theories["0.3mm"].to_parquet(run)
    bench = load_bench(shipped_bench("ninebar-testbed"))
    short = tmp_path / "short.mcap"
    record_session(open_rig(bench, "sim", {"speedup": math.inf, "config": EMULATOR}), bench,
                   SessionPlan(speed=bench.speed, cycles=1), short)
    data = files["0.3mm"].read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(0.9 * len(data))])
    out = tmp_path / "report"
    code = main(["compare", str(short), str(cut), "--out", str(out), "--theory", str(run),
                 "--windows", "random:1:3", "--cycles", "2"])
    assert code == 1  # not everything was scored
    err = capsys.readouterr().err
    assert f"not scored: {short}" in err and f"{cut}: unfinished session" in err
    scores = json.loads((out / "scores.json").read_text())
    assert [s["label"] for s in scores["sessions"]] == ["cut (unfinished)"]
