"""Bad input at the command line gets one clear line and exit 2, before any work starts; values that
look like negative quantities are values; shipped bench names work in every command taking a bench."""

from __future__ import annotations

import pytest
from wearbench.bench.load import BENCH_DIR, shipped_bench
from wearbench.cli import build_parser, main

RECORD = ["record", "ninebar-testbed", "--backend", "sim", "--out"]


@pytest.mark.parametrize("bad", [
    ["--cycles", "-5"], ["--cycles", "0"], ["--cycles", "nan"], ["--cycles", "inf"], ["--duration=0s"],
    ["--duration", "-1s"], ["--duration", "nan s"], ["--cycles", "2", "--speed", "nan"],
    ["--cycles", "2", "--settle", "-1s"],
])
def test_record_counts_and_durations_are_checked_at_the_edge(bad, tmp_path, capsys):
    out = tmp_path / "s.mcap"
    with pytest.raises(SystemExit) as info:  # argparse's own exit, or ours below
        raise SystemExit(main([*RECORD, str(out), *bad]))
    assert info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err and "Traceback" not in err[-1]
    assert any(word in err[-1] for word in ("expected", "not a number")), err[-1]
    assert not out.exists()


@pytest.mark.parametrize("argv", [
    ["wear", "ninebar", "--stage-cycles", "0", "--out", "w"], ["wear", "ninebar", "--stages", "0", "--out", "w"],
    ["simulate", "ninebar", "--revolutions", "0"], ["simulate", "ninebar", "--revolutions", "nan"],
    ["sweep", "ninebar", "--vary", "speed=1..2:2", "--realisations", "0", "--out", "s"],
    ["compare", "s.mcap", "--cycles", "0"], ["study", "ninebar", "--cycles", "0"],
])
def test_other_counts_are_checked_at_the_edge(argv, capsys):
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    assert "expected" in capsys.readouterr().err


@pytest.mark.parametrize("command", [["record", "ninebar-testbed", "--cycles", "1", "--out", "s.mcap"],
                                     ["simulate", "ninebar"], ["wear", "ninebar", "--out", "w"]])
def test_negative_quantity_as_a_separate_argument(command):
    args = build_parser().parse_args([*command, "--speed", "-2pi"])
    assert args.speed == "-2pi"


def test_simulate_takes_negative_speed_through_the_command_line():
    parser = build_parser()
    assert parser.parse_args(["simulate", "ninebar", "--speed", "-5pi"]).speed == "-5pi"
    assert parser.parse_args(["simulate", "ninebar", "--speed", "-.5"]).speed == "-.5"


def test_a_bench_that_cannot_record(tmp_path, capsys):
    text = shipped_bench("fourbar").read_text()
    encoder = text[text.index('[[sensor]]\nname = "crank_encoder"'):text.index("[hardware]")]
    fourbar = tmp_path / "no-encoder.toml"
    fourbar.write_text(text.replace(encoder, ""))
    assert main(["bench", "check", str(fourbar)]) == 0
    assert "cannot record: no encoder" in capsys.readouterr().out
    out = tmp_path / "s.mcap"
    assert main(["record", str(fourbar), "--backend", "sim", "--cycles", "1", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(fourbar) in err and "encoder" in err
    assert not out.exists()


@pytest.mark.parametrize("path", sorted(BENCH_DIR.glob("*.toml")), ids=lambda p: p.stem)
def test_every_shipped_bench_checks_and_can_record(path, capsys):
    """Issue 44: the shipped benches are lab-ready: they pass every check, their cranks turn, their
    accelerometer's range is above the motion alone, and they have both sensors a session records."""
    assert main(["bench", "check", str(path)]) == 0
    out = capsys.readouterr().out
    assert "full revolutions" in out and "% of its" in out and "cannot record" not in out, out


ENCODER_ON_Q = """[[sensor]]
name = "rocker_encoder"
kind = "encoder"
joint = "Q"
counts_per_rev = 4000
sample_rate = "1 kHz"

"""
COUPLER_ACC = """[[sensor]]
name = "coupler_acc"
kind = "accelerometer"
body = "coupler"
point = "end"
axis = "0 deg"
range = "500 g"
sample_rate = "10 kHz"

"""
NOT_GRASHOF = (('length = "0.10 m"\nmass = "0.2355 kg"', 'length = "0.28 m"\nmass = "0.2355 kg"'),
               ('P = ["0 m", "0.10 m"]', 'P = ["0 m", "0.28 m"]'))

# issue 44: what 'bench check' used to pass -> (replacements of the shipped fourbar, the start of the
# one line: file, key and value, and what it expected)
CHECK_REFUSALS = {
    "crank that cannot turn (not Grashof)": (NOT_GRASHOF, "driver[0].joint = 'O': ",
                                             "expected cranks that turn full revolutions"),
    "encoder on a joint not driven": ((('joint = "O"                       # on', 'joint = "Q"  # on'),),
                                      "sensor[1] (crank_encoder).joint = 'Q': ",
                                      "expected a driven joint, one of the [[driver]] joints ['O']"),
    "second encoder": ((("[hardware]", ENCODER_ON_Q + "[hardware]"),), "sensor[2] (rocker_encoder).kind = 'encoder': ",
                       "expected one encoder per bench"),
    "second accelerometer": ((("[hardware]", COUPLER_ACC + "[hardware]"),),
                             "sensor[2] (coupler_acc).kind = 'accelerometer': ",
                             "expected one accelerometer per bench: sensor[0] (rocker_acc) is the one wearbench uses"),
    "range below the motion alone": ((('range = "500 g"', 'range = "0.5 g"'),), "sensor[0] (rocker_acc).range = '0.5 g': ",
                                     "expected a range above the 0.689 g"),
    "emulator truth names no state": ((('state = "0.3 mm new"              #', 'state = "0.4 mm new"  #'),),
                                      "emulator.truth.state = '0.4 mm new': ",
                                      "expected one of the bench's [[state]] names: ['0.3 mm new', '0.6 mm new']"),
}


@pytest.mark.parametrize("case", sorted(CHECK_REFUSALS))
def test_bench_check_refuses_what_it_used_to_pass(case, tmp_path, capsys, monkeypatch):
    """One line naming file, key, value and expectation, exit 2, in seconds: no simulation runs."""
    import wearbench.model
    from wearbench.model import simulation

    replacements, start, expected = CHECK_REFUSALS[case]
    text = shipped_bench("fourbar").read_text()
    for old, new in replacements:
        assert old in text, old
        text = text.replace(old, new, 1)
    path = tmp_path / "mybench.toml"
    path.write_text(text)
    for module in (wearbench.model, simulation):
        monkeypatch.setattr(module, "simulate", lambda *a, **k: pytest.fail("bench check simulated"))
    assert main(["bench", "check", str(path)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and f"{path}: {start}" in err[0] and expected in err[0], err


def test_resolve_bench(tmp_path, monkeypatch):
    from wearbench.bench.load import resolve_bench

    monkeypatch.chdir(tmp_path)
    assert resolve_bench("ninebar-testbed") == BENCH_DIR / "ninebar-testbed.toml"
    assert resolve_bench("ninebar-testbed.toml") == BENCH_DIR / "ninebar-testbed.toml"
    local = tmp_path / "ninebar-testbed.toml"
    local.write_text("")
    assert resolve_bench("ninebar-testbed.toml").resolve() == local  # a file here wins over a shipped name
    with pytest.raises(FileNotFoundError, match="shipped: .*ninebar-testbed"):
        resolve_bench("no-such-bench")


@pytest.mark.parametrize("argv", [["bench", "check", "ninebar-testbed"], ["bench", "show", "ninebar-testbed"]])
def test_shipped_names_in_bench_commands(argv, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 0
    assert "ninebar-testbed" in capsys.readouterr().out


def test_every_bench_command_resolves_shipped_names():
    """Every subcommand with a bench argument goes through resolve_bench (no private resolver)."""
    import inspect

    from wearbench import cli

    for name in ("bench", "wear", "study", "sweep", "simulate", "record", "emulate", "ensemble"):
        source = inspect.getsource(__import__(f"wearbench.cli.{cli.COMMANDS[name]}", fromlist=["run"]))
        assert "resolve_bench(" in source and "shipped_bench(" not in source, name


def test_bench_show_headers_keep_their_units(capsys):
    assert main(["bench", "show", "ninebar"]) == 0
    out = capsys.readouterr().out
    for header in ("mass [kg]", "inertia [kg m^2]", "clearance [mm]"):
        assert header in out


@pytest.mark.parametrize("argv, value", [
    (["simulate", "ninebar"], "fast"), (["simulate", "ninebar"], "1e400"),
    (["wear", "ninebar", "--out", "w"], "0"), (["wear", "ninebar", "--out", "w"], "nan"),
    (["ensemble", "ninebar-testbed", "--out", "e.npz"], "0"),
    (["ensemble", "ninebar-testbed", "--out", "e.npz"], "1e6rpm"),  # beyond the motor's max_speed
    ([*RECORD, "s.mcap", "--cycles", "1"], "1e6rpm"), ([*RECORD, "s.mcap", "--cycles", "1"], "0"),
])
def test_every_speed_goes_through_one_check(argv, value, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main([*argv, "--speed", value]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"--speed {value!r}" in err and "expected" in err, err
    assert "motor speed" in err or "max_speed" in err, err
    assert list(tmp_path.iterdir()) == []  # refused before any work


def test_a_swept_speed_goes_through_the_same_check(tmp_path, capsys):
    assert main(["sweep", "ninebar", "--vary", "speed=-1..1:3", "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--vary speed '0rad/s'" in err and "other than 0" in err, err
    assert not (tmp_path / "s").exists()


@pytest.mark.parametrize("argv, words", [
    (["sweep", "ninebar", "--vary", "speed=1e6rpm", "--out", "s"], ["--vary speed", "max_speed"]),
    (["sweep", "ninebar", "--vary", "clearance=0mm,0.3mm", "--out", "s"], ["--vary clearance '0mm'", "bearing radius"]),
    (["sweep", "ninebar", "--vary", "clearance.A=50mm", "--out", "s"], ["--vary clearance.A '50mm'", "bearing radius"]),
    (["sweep", "ninebar", "--vary", "wear_coefficient=-5e-14", "--out", "s"], ["--vary wear_coefficient", ">= 0"]),
    (["simulate", "ninebar", "--clearance", "-0.1mm"], ["--clearance '-0.1mm'", "bearing radius"]),
    (["wear", "ninebar", "--clearance", "A=90mm", "--out", "w"], ["--clearance 'A=90mm'", "bearing radius"]),
    (["wear", "ninebar", "--wear-coefficient", "-5e-14", "--out", "w"], ["--wear-coefficient '-5e-14'", ">= 0"]),
    ([*RECORD, "s.mcap", "--cycles", "2", "--wear", "A=worn"], ["--wear A=worn", "neither 'new' nor a worn-surface file"]),
    ([*RECORD, "s.mcap", "--cycles", "2", "--clearance", "A=0mm"], ["--clearance 'A=0mm'", "bearing radius"]),
    (["ensemble", "ninebar-testbed", "--realisations", "3", "--out", "e.npz"], ["--realisations 3", "at least 4"]),
])
def test_nonsense_is_refused_naming_option_value_and_expectation(argv, words, tmp_path, monkeypatch, capsys):
    """Issue 25, item 13: each used to be accepted (and run, or written as a file identify refuses)."""
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = [x for x in capsys.readouterr().err.splitlines() if not x.startswith("compiling")]
    assert len(err) == 1 and all(w in err[0] for w in words), err
    assert list(tmp_path.iterdir()) == []  # refused before any work


def test_record_cycles_below_one_are_refused(tmp_path, capsys):
    with pytest.raises(SystemExit) as info:
        main([*RECORD, str(tmp_path / "s.mcap"), "--cycles", "1e-9"])
    assert info.value.code == 2 and "expected at least 1 crank cycle" in capsys.readouterr().err


def test_record_refuses_a_crank_that_cannot_turn_before_the_emulator_simulates(tmp_path, capsys):
    text = shipped_bench("fourbar").read_text()
    for old, new in NOT_GRASHOF:
        text = text.replace(old, new, 1)
    path = tmp_path / "locked.toml"
    path.write_text(text)
    out = tmp_path / "s.mcap"
    assert main(["record", str(path), "--backend", "sim", "--cycles", "1", "--out", str(out)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and f"{path}: driver[0].joint = 'O': expected cranks that turn full revolutions" in err[0]
    assert not out.exists()


@pytest.mark.parametrize("option, labels, words", [
    ("speedup=fast", [], ["[hardware.sim] speedup = 'fast': expected a positive number"]),
    ("step=-1", [], ["[hardware.sim] step = -1: expected a positive number"]),
    ("configg=x.json", [], ["unknown option(s) ['configg']", "expected speedup, step, config"]),
    ("config=LIST", [], ["LIST: emulator = [1, 2]: expected a table"]),
    ("config=NOT_JSON", [], ["config = ", "NOT_JSON", "expected a JSON file of the [emulator] table"]),
    ("config=BAD_STATE", [], [("BAD_STATE: emulator.truth.state = '0.4 mm new': expected one of the bench's "
                               "[[state]] names")]),
    ("config=BAD_STATE", ["--wear", "R=new"], ["BAD_STATE: emulator.truth.state = '0.4 mm new'"]),
    ("config=BAD_KEY", ["--clearance", "R=0.3mm"], ["BAD_KEY: emulator.acelerometer = {}: unknown key"]),
])
def test_the_emulators_configuration_is_checked_before_it_starts(option, labels, words, tmp_path, capsys):
    """Issue 44: ``--option config=JSON`` (the [emulator] table as one JSON object) and the sim backend's
    other options: a bad key or value is one line naming it, exit 2, no session file."""
    files = {"LIST": "[1, 2]", "NOT_JSON": "truth = 1", "BAD_STATE": '{"truth": {"state": "0.4 mm new"}}',
             "BAD_KEY": '{"acelerometer": {}}'}
    for name, content in files.items():
        (tmp_path / f"{name}.json").write_text(content)
        option = option.replace(name, str(tmp_path / f"{name}.json"))
        words = [w.replace(name, str(tmp_path / f"{name}.json")) for w in words]
    out = tmp_path / "s.mcap"
    assert main(["record", "fourbar", "--backend", "sim", "--cycles", "1", "--out", str(out), "--option", option,
                 *labels]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and all(w in err[0] for w in words), err
    assert not out.exists()
