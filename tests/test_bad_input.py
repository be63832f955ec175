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
    fourbar = shipped_bench("fourbar")
    assert main(["bench", "check", str(fourbar)]) == 0
    assert "cannot record: no encoder" in capsys.readouterr().out
    out = tmp_path / "s.mcap"
    assert main(["record", str(fourbar), "--backend", "sim", "--cycles", "1", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(fourbar) in err and "encoder" in err
    assert not out.exists()


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
