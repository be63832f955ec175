"""A session whose bench file is recorded but names worn-surface files missing beside it (issue 45,
item 6): `track` and `estimate` pass on the session loader's own words (the file that does not
exist), never "no bench file recorded in it"; a session with no bench file recorded still says that."""

from __future__ import annotations

import json
import shutil
from dataclasses import replace

import pytest
from wearbench.bench.load import shipped_bench
from wearbench.cli import main
from wearbench.validation.measurement.session import load_session
from wearbench.validation.workflows.session_set import SessionSet

from ...acquisition.conftest import FAST, HARMONIC


@pytest.fixture(scope="module")
def orphans(tmp_path_factory):
    """Two sessions of a copy of the test bed whose worn states name surface files by absolute paths
    (so the sessions carry no copies of them), those files then deleted."""
    tmp = tmp_path_factory.mktemp("orphans")
    src = shipped_bench("ninebar-testbed")
    worn = tmp / "worn"
    shutil.copytree(src.parent / "worn", worn)
    bench = tmp / "bench" / "testbed.toml"
    bench.parent.mkdir()
    bench.write_text(src.read_text().replace('"worn/', f'"{worn}/'))
    config = tmp / "emulator.json"
    config.write_text(json.dumps(HARMONIC))
    out = []
    for name, n in (("s0.mcap", "0"), ("s1.mcap", "150000")):
        assert main(["record", str(bench), "--backend", "sim", "--option", "speedup=inf", "--option",
                     f"config={config}", "--speed", f"{FAST}", "--cycles", "2", "--out", str(tmp / name),
                     "--cycles-run", n]) == 0
        out.append(tmp / name)
    shutil.rmtree(worn)
    return out, worn


def test_the_loader_says_which_named_file_is_missing(orphans):
    (s0, _), worn = orphans
    s = load_session(s0)
    assert s.bench is None and s.bench_problem.startswith("the recorded bench does not load here: ")
    assert f"{worn}/ninebar-testbed_A_200k.npz does not exist" in s.bench_problem
    assert "bench/testbed.toml" in s.bench_problem  # the bench file where it was recorded
    with pytest.raises(ValueError) as e:
        SessionSet([s], calibration=None).require_benches("tracking needs one")
    assert str(e.value) == f"session s0: {s.bench_problem}; tracking needs one"


@pytest.mark.parametrize("command", ["track", "estimate"])
def test_track_and_estimate_pass_on_the_loaders_words(orphans, command, capsys):
    (s0, s1), worn = orphans
    assert main([command, str(s0), str(s1), "--calibration", "none"]) != 0
    err = capsys.readouterr().err
    assert "session s0: the recorded bench does not load here: " in err, err
    assert f"{worn}/ninebar-testbed_A_200k.npz does not exist" in err and "no bench file recorded" not in err


def test_a_session_without_a_recorded_bench_still_says_so(orphans):
    (s0, _), _ = orphans
    s = replace(load_session(s0), bench_problem=None)
    with pytest.raises(ValueError, match="session s0: no bench file recorded in it; the estimator needs its bench"):
        SessionSet([s], calibration=None).require_benches("the estimator needs its bench")
