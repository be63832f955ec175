"""The command line: one entry point whose help lists every subcommand, each with its own help."""

from __future__ import annotations

import argparse
import subprocess
import sys

import pytest
from wearbench.bench.load import shipped_bench
from wearbench.cli import COMMANDS, build_parser, main


def test_help_lists_every_subcommand(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    for name in COMMANDS:
        assert name in out


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_each_subcommand_has_useful_help(name, capsys):
    with pytest.raises(SystemExit) as info:
        main([name, "--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    assert f"wearbench {name}" in out
    assert "not built yet" not in out
    assert len(out.splitlines()) >= 6


def _commands(parser) -> dict:
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices


def test_a_command_builds_its_own_parser_only_and_it_is_the_full_parsers():
    """``wearbench COMMAND`` parses with that command's parser alone: the same help, so the same
    options and defaults, as in the full parser (``wearbench --help``, the reference)."""
    full = _commands(build_parser())
    for name in COMMANDS:
        own = _commands(build_parser(name))
        assert list(own) == [name]
        assert own[name].format_help() == full[name].format_help()


def test_a_command_starts_without_the_other_commands_imports():
    """In a fresh interpreter, ``inspect``'s parser loads neither the demo's truths nor the model's
    compiler; the full parser does (what every command paid before)."""
    heavy = ("wearbench.cli.demo", "wearbench.synthetic.truths", "numba", "scipy.signal")
    code = ("import sys\nfrom wearbench.cli import build_parser\nbuild_parser({})\n"
            f"print(sorted(m for m in {heavy!r} if m in sys.modules))\n")
    loaded = {c: subprocess.run([sys.executable, "-c", code.format(c)], capture_output=True, text=True, check=True,
                                timeout=120).stdout.strip() for c in ("'inspect'", "None")}
    assert loaded["'inspect'"] == "[]"
    assert loaded["None"] == repr(sorted(heavy))


@pytest.mark.parametrize("command", ["identify", "compare", "calibrate"])
def test_ensemble_size_defaults_are_the_shipped_ensembles(command):
    """The command line's ensemble size is EnsembleSettings' (the literals in cli/ keep the start fast)."""
    from wearbench.cli.compute import ensemble_size
    from wearbench.validation.inference.ensemble import EnsembleSettings

    args = build_parser().parse_args(["ensemble", "b.toml"])
    assert (args.realisations, args.cycles) == (EnsembleSettings().realisations, EnsembleSettings().cycles)
    size = ensemble_size(build_parser().parse_args([command, "s.mcap", *(["--state", "x"] * (command == "calibrate"))]))
    assert (size.realisations, size.cycles) == (EnsembleSettings().realisations, EnsembleSettings().cycles)


def test_estimator_defaults_are_the_shipped_estimator():
    """`wearbench estimator`'s design defaults resolve to EstimatorDesign() on the test bed (the bench's
    own rule, ``EstimatorDesign.for_bench``), and the test bed's shipped
    estimator has that design's key: `estimate`, `identify --estimate` and the demo use it instead of
    building one (regenerate it when this fails: `wearbench estimator
    ninebar-testbed --ship --force`, then its move, README "How large ...")."""
    from wearbench.bench.load import load_bench
    from wearbench.cli.estimator import design_from_args
    from wearbench.validation.estimation.estimate import (
        EstimatorDesign,
        default_spread,
        estimator_key,
        load_estimator,
    )
    from wearbench.validation.estimation.spread import spread_key
    from wearbench.validation.inference.artefacts import shipped_path

    bench = load_bench(shipped_bench("ninebar-testbed"))
    assert design_from_args(build_parser().parse_args(["estimator", "b.toml"])).resolve(bench) == EstimatorDesign()
    key = estimator_key(bench, EstimatorDesign(), bench.speed)
    est = load_estimator(shipped_path("estimator", bench.name), key=key)
    assert est is not None, "stale: the model, bench or design changed"
    # its wear spread beside it (`wearbench estimator ninebar-testbed --ship` adds a missing or stale one)
    assert est.spread is not None and est.spread.key == spread_key(key, default_spread(EstimatorDesign()))
    assert est.spread.covariance[0].max() == 0 and est.spread.covariance[-1].trace() > 0


def test_bench_check_reports_degrees_of_freedom(capsys):
    assert main(["bench", "check", str(shipped_bench("ninebar"))]) == 0
    out = capsys.readouterr().out
    assert "ok" in out and "4 degrees of freedom" in out


@pytest.mark.slow
def test_user_error_is_one_line_and_exit_2(tmp_path):
    broken = tmp_path / "broken.toml"
    broken.write_text(shipped_bench("ninebar").read_text().replace('length = "0.40 m"', 'length = "-0.4 m"', 1))
    proc = subprocess.run([sys.executable, "-m", "wearbench.cli", "bench", "check", str(broken)],
                          check=False, capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and str(broken) in proc.stderr and "positive length" in proc.stderr
