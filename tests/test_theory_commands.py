"""Issue 44, items 2 and 4: every command that builds theory takes the same compute options, says how
many realisations it will build and about how much CPU time that takes before it starts, and checks
every size and design value before any simulation, refusing in one line that names the option.

The sessions are the four-bar's (no shipped theory: every command must build) with the emulator's
harmonic signal (no model run to record them). ``run_tasks`` is replaced by a refusal, so a test that
gets its own message never reached a simulation; the pilot that prices a revolution is replaced by a
constant except in its own test."""

from __future__ import annotations

import json

import pytest
from wearbench.bench.load import shipped_bench
from wearbench.cli import build_parser, main

from .acquisition.conftest import HARMONIC

REACHED = "a batch of simulations was started"
COMMON = ["--workers", "0", "--scheduler", "local", "--realisations", "8", "--ensemble-cycles", "6"]
NOT_GRASHOF = (('length = "0.10 m"\nmass = "0.2355 kg"', 'length = "0.28 m"\nmass = "0.2355 kg"'),
               ('P = ["0 m", "0.10 m"]', 'P = ["0 m", "0.28 m"]'))


@pytest.fixture(scope="module")
def sessions(tmp_path_factory):
    """Two harmonic sessions of the four-bar, one labelled with each of its states, with cycles run."""
    where = tmp_path_factory.mktemp("fourbar")
    config = where / "emulator.json"
    config.write_text(json.dumps(HARMONIC))
    out = []
    for clearance, run in (("0.3mm", 0), ("0.6mm", 200_000)):
        path = where / f"s_{clearance}.mcap"
        assert main(["record", "fourbar", "--backend", "sim", "--option", "speedup=inf", "--option", f"config={config}",
                     "--clearance", f"R={clearance}", "--cycles", "8", "--cycles-run", str(run),
                     "--out", str(path)]) == 0
        out.append(str(path))
    return out


@pytest.fixture
def no_simulation(monkeypatch):
    """Any batch of simulations refuses to start; a revolution costs a quarter of a second."""

    def refuse(*args, **kwargs):
        raise RuntimeError(REACHED)

    monkeypatch.setattr("wearbench.compute.run_tasks", refuse)
    monkeypatch.setattr("wearbench.compute.cost.revolution_seconds", lambda cost: 0.25)


def commands(s: list[str], tmp: str) -> dict[str, list[str]]:
    return {"identify": ["identify", *s],
            "compare": ["compare", *s, "--out", f"{tmp}/report"],
            "calibrate": ["calibrate", s[0], "--state", "0.3 mm new", "--dir", f"{tmp}/cal"],
            "estimate": ["estimate", *s],
            "estimator": ["estimator", "fourbar", "--out", f"{tmp}/e.npz"],
            "track": ["track", *s]}


@pytest.mark.parametrize("command", ["identify", "compare", "calibrate", "estimate", "estimator", "track"])
def test_every_theory_command_takes_the_same_compute_options(command):
    ready = {"identify": ["--ensembles", "e.npz", "--estimator", "x.npz"], "compare": ["--ensembles", "e.npz"],
             "calibrate": ["--ensembles", "e.npz"], "estimate": ["--estimator", "x.npz"], "estimator": [],
             "track": ["--estimator", "x.npz"]}[command]
    argv = commands(["s.mcap"], ".")[command]
    args = build_parser().parse_args([*argv, *COMMON, "--small", *ready])
    assert (args.workers, args.scheduler, args.realisations, args.ensemble_cycles, args.small) == (0, "local", 8, 6,
                                                                                                    True)


@pytest.mark.parametrize(("command", "says"), [
    ("identify", "theory ensembles: 16 realisations, about 36 s of CPU"),  # 2 states x 8 x (6 + 1 + 2) revolutions
    ("compare", "theory ensembles: 16 realisations, about 36 s of CPU"),
    ("calibrate", "theory ensembles: 16 realisations, about 36 s of CPU"),
    ("estimate", "estimator: 5 wear runs and 160 realisations, about"),  # 5 x 4 design points x 8
    ("estimator", "estimator: 5 wear runs and 160 realisations, about"),
    ("track", "estimator: 5 wear runs and 160 realisations, about"),
])
def test_every_builder_says_what_it_builds_and_its_cpu_time_before_it_starts(command, says, sessions, tmp_path,
                                                                             no_simulation, capsys):
    capsys.readouterr()
    assert main([*commands(sessions, str(tmp_path))[command], *COMMON]) == 2
    err = capsys.readouterr().err.splitlines()
    said = next(i for i, line in enumerate(err) if says in line)
    assert "of CPU" in err[said] and "s per motor revolution, measured on this machine" in err[said]
    assert said < next(i for i, line in enumerate(err) if REACHED in line)


def test_a_small_design_is_offered_and_priced(sessions, tmp_path, no_simulation, capsys):
    assert main(["estimate", sessions[0], "--small", "--workers", "0"]) == 2
    err = capsys.readouterr().err
    assert "estimator: 3 wear runs and 27 realisations" in err  # 3 x 3 points x 3 realisations


def test_the_wear_spread_is_priced_in_the_estimators_plan_and_checked_first(tmp_path, no_simulation, capsys):
    """A design of 12 realisations gets the default spread: 3 drawn benches' wear runs per clearance
    and 12 realisations of each of their 3 worn points, priced in the one plan line before anything
    starts; a spread the design cannot pair is refused before it."""
    argv = ["estimator", "fourbar", "--out", str(tmp_path / "e.npz"), "--workers", "0", "--ensemble-cycles", "6"]
    assert main([*argv, "--realisations", "12"]) == 2
    err = capsys.readouterr().err
    assert "estimator: 5 wear runs and 240 realisations and 15 spread wear runs and 540 spread realisations, about" in err
    assert main([*argv, "--realisations", "8", "--wear-runs", "2"]) == 2
    err = capsys.readouterr().err
    assert "--wear-runs 2: the spread pairs 12 realisations" in err and REACHED not in err


def test_the_pilot_prices_a_revolution_once_and_keeps_it(monkeypatch):
    """The price of a revolution is measured (CPU clock) on the bench, state and speed, then read back;
    another model source with the same outputs (an equivalence entry: it may run faster) is priced afresh."""
    from wearbench.bench.load import load_bench
    from wearbench.compute import cost

    bench = load_bench(shipped_bench("slider-crank"))
    what = cost.Cost(bench, bench.states[0], bench.speed, 200_000.0, "realisations")
    first = cost.revolution_seconds(what)
    assert 0 < first < 60

    def no_more(*args, **kwargs):
        raise AssertionError("measured again")

    monkeypatch.setattr("wearbench.model.realisation.simulate_state", no_more)
    assert cost.revolution_seconds(what) == first
    monkeypatch.setattr("wearbench.compute.cost.model_source_digest", lambda: "0" * 64)
    with pytest.raises(AssertionError, match="measured again"):
        cost.revolution_seconds(what)


@pytest.mark.parametrize(("argv", "words"), [
    (["identify", "S0", "--ensemble-cycles", "5"], ["--ensemble-cycles 5: expected at least 6 settled cycles"]),
    (["compare", "S0", "--ensemble-cycles", "5", "--out", "r"], ["--ensemble-cycles 5: expected at least 6"]),
    (["compare", "S0", "--cycles", "7", "--ensemble-cycles", "7", "--out", "r"],
     ["--ensemble-cycles 7: expected at least 8"]),
    (["identify", "S0", "--realisations", "3"], ["--realisations 3: expected at least 4"]),
    (["calibrate", "S0", "--state", "0.3 mm new", "--ensemble-cycles", "1"], ["--ensemble-cycles 1: expected at least 2"]),
    (["calibrate", "S0", "--state", "0.9 mm worn"], ["--state '0.9 mm worn': expected one of the bench's states"]),
    (["estimate", "S0", "--ensemble-cycles", "1"], ["--ensemble-cycles 1: expected at least 2"]),
    (["estimate", "S0", "--realisations", "2"], ["--realisations 2: expected at least 3"]),
    (["estimate", "S0", "--design-clearances", "0.3mm,12mm"],
     ["--design-clearances 0.3mm,12mm: expected clearances below fourbar's smallest bearing radius 10 mm"]),
    (["estimate", "S0", "--design-clearances", "0.3mm"], ["--design-clearances 0.3mm: expected at least two"]),
    (["track", "S0", "S1", "--design-cycles", "0,100000,300000"],
     ["--design-cycles 0,100000,300000: expected at least two cycles-run values equally spaced from 0"]),
    (["track", "S0", "S1", "--design-cycles", "0,1e5,x"], ["--design-cycles '0,1e5,x': expected cycles-run numbers"]),
    (["estimator", "fourbar", "--lives", "2", "--out", "e.npz"], ["--lives 2: expected at least 3 lives"]),
    (["estimator", "fourbar", "--life-factor", "2", "--lives", "3", "--out", "e.npz"],
     ["--life-factor 2: expected a wear factor in (0, 1.5]"]),
])
def test_every_size_and_design_value_is_checked_before_any_simulation(argv, words, sessions, tmp_path, monkeypatch,
                                                                       no_simulation, capsys):
    monkeypatch.chdir(tmp_path)
    argv = [sessions[0] if a == "S0" else sessions[1] if a == "S1" else a for a in argv]
    capsys.readouterr()
    assert main([*argv, "--workers", "0"]) == 2
    err = [x for x in capsys.readouterr().err.splitlines() if not x.startswith("compiling")]
    assert len(err) == 1 and all(w in err[0] for w in words), err
    assert REACHED not in err[0] and list(tmp_path.iterdir()) == []


def test_a_bench_whose_sensor_cannot_see_impacts_at_its_speed_is_refused_first(tmp_path, no_simulation, capsys):
    text = shipped_bench("fourbar").read_text().replace('sample_rate = "10 kHz"', 'sample_rate = "100 Hz"', 1)
    path = tmp_path / "blind.toml"
    path.write_text(text)
    assert main(["estimator", str(path), "--out", str(tmp_path / "e.npz"), "--workers", "0"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "at a 1 Hz crank (60 rpm) every impact band lies above" in err[0], err
    assert "45 Hz" in err[0] and "cannot see impacts at this speed" in err[0]


def test_simulate_refuses_a_crank_that_cannot_turn_before_it_simulates(tmp_path, monkeypatch, capsys):
    """It ran for five minutes and failed; the kinematic sweep refuses it in seconds."""
    text = shipped_bench("fourbar").read_text()
    for old, new in NOT_GRASHOF:
        text = text.replace(old, new, 1)
    path = tmp_path / "locked.toml"
    path.write_text(text)

    def no_simulation(*args, **kwargs):
        raise AssertionError("simulated")

    monkeypatch.setattr("wearbench.model.simulate", no_simulation)
    assert main(["simulate", str(path), "--revolutions", "1"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and f"{path}: driver[0].joint = 'O': expected cranks that turn full revolutions" in err[0]
