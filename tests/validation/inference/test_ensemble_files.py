"""Issue 25, item 7 (and the .npz part of 11): a saved ensembles file carries the bench, speed and
candidates it was built for, and `identify --ensembles` refuses, in one line naming the mismatch,
a file that does not fit the session (a 3 pi session against 2 pi ensembles used to get "none of
the candidates" with no hint why; --candidates beside --ensembles was silently ignored), or that is
no ensembles file at all (KeyError, BadZipFile tracebacks before)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.cli import main
from wearbench.validation.inference.ensemble import (
    Ensemble,
    EnsembleSettings,
    ensembles_key,
    save_ensembles,
)

from ...acquisition.conftest import FAST, HARMONIC

SETTINGS = EnsembleSettings(realisations=4, cycles=5)


def _ensembles(bench, speed, realisations=4):
    """Stand-in ensembles (the refusals come before any use of their numbers)."""
    rng = np.random.default_rng(0)
    p, c = SETTINGS.features.size, SETTINGS.cycles
    return {s.name: Ensemble(s.name, SETTINGS, rng.normal(size=(realisations, c, p)),
                             rng.normal(size=(realisations, c, 720)), rng.normal(size=(realisations, c)), speed)
            for s in bench.states}


def _save(bench, speed, path, realisations=4):
    return save_ensembles(_ensembles(bench, speed, realisations), path,
                          key=ensembles_key(bench, bench.states, speed, SETTINGS), bench=bench, states=bench.states)


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    where = tmp_path_factory.mktemp("session")
    config = where / "emulator.json"
    config.write_text(json.dumps(HARMONIC))
    out = where / "s.mcap"
    assert main(["record", "ninebar-testbed", "--backend", "sim", "--option", "speedup=inf", "--option",
                 f"config={config}", "--speed", f"{FAST}", "--cycles", "3", "--out", str(out)]) == 0
    return out


def _refused(capsys, args) -> str:
    capsys.readouterr()
    assert main(["identify", *args]) == 2
    err = [x for x in capsys.readouterr().err.splitlines() if not x.startswith("compiling")]
    assert len(err) == 1 and "Traceback" not in err[0], err
    return err[0]


def test_ensembles_that_do_not_fit_the_session_are_refused_naming_why(session, tmp_path, capsys):
    testbed = load_bench(shipped_bench("ninebar-testbed"))
    other_speed = _save(testbed, 2 * math.pi, tmp_path / "2pi.npz")
    err = _refused(capsys, [str(session), "--ensembles", str(other_speed)])
    assert str(other_speed) in err and "built at 6.28319 rad/s" in err and f"{FAST:g} rad/s" in err
    ninebar = load_bench(shipped_bench("ninebar"))
    if not ninebar.states:  # a bench of its own: the test bed's states on the paper's mechanism
        ninebar = ninebar.__class__(**{**ninebar.__dict__, "states": testbed.states})
    other_bench = _save(ninebar, FAST, tmp_path / "ninebar.npz")
    err = _refused(capsys, [str(session), "--ensembles", str(other_bench)])
    assert "built for bench 'ninebar'" in err and "'ninebar-testbed'" in err
    fits = _save(testbed, FAST, tmp_path / "fits.npz")
    states = tmp_path / "states.toml"
    states.write_text('[[state]]\nname = "loose"\nclearances = { A = "0.5 mm", B = "0.5 mm" }\n')
    err = _refused(capsys, [str(session), "--ensembles", str(fits), "--candidates", str(states)])
    assert "built for the candidate states" in err and "['loose']" in err
    few = _save(testbed, FAST, tmp_path / "few.npz", realisations=3)
    err = _refused(capsys, [str(session), "--ensembles", str(few)])
    assert "3 realisations per state; identification needs at least 4" in err


def test_files_that_are_not_ensembles_are_one_line(session, tmp_path, capsys):
    wrong = tmp_path / "wrong.npz"
    np.savez(wrong, x=np.arange(3))
    assert "not an ensembles file" in _refused(capsys, [str(session), "--ensembles", str(wrong)])
    testbed = load_bench(shipped_bench("ninebar-testbed"))
    cut = tmp_path / "cut.npz"
    cut.write_bytes(_save(testbed, FAST, tmp_path / "whole.npz").read_bytes()[:2000])
    assert "not an ensembles file" in _refused(capsys, [str(session), "--ensembles", str(cut)])
    text = tmp_path / "text.npz"
    text.write_text("hello")
    err = _refused(capsys, [str(session), "--ensembles", str(text)])
    assert "not an ensembles file" in err and "allow_pickle" not in err
    assert "--realisations 3: expected at least 4" in _refused(capsys, [str(session), "--realisations", "3"])


def test_a_candidate_surface_that_is_no_npz_fails_before_any_realisation(tmp_path, monkeypatch, capsys):
    """Issue 25, item 13: a --candidates wear file that is not an .npz submitted all realisations and
    then failed with numpy's advice to load pickles unsafely."""
    from wearbench import compute

    monkeypatch.setattr(compute, "run_tasks", lambda *a, **k: pytest.fail("realisations submitted"))
    bad = tmp_path / "worn.npz"
    bad.write_text("not surfaces")
    states = tmp_path / "states.toml"
    states.write_text(f'[[state]]\nname = "worn"\nwear = {{ A = "{bad}" }}\n')
    capsys.readouterr()
    assert main(["ensemble", "ninebar-testbed", "--candidates", str(states), "--out", str(tmp_path / "e.npz")]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "candidate state 'worn', joint A" in err and "not an .npz archive" in err and "pickle" not in err


@pytest.mark.slow
def test_off_a_terminal_progress_is_lines_and_the_table_is_whole(session, tmp_path):
    """Issue 25, item 12: off a terminal identify was silent for minutes while it built ensembles
    and cut its verdict table to 80 columns ("undeci...")."""
    import subprocess
    import sys

    testbed = load_bench(shipped_bench("ninebar-testbed"))
    fits = _save(testbed, FAST, tmp_path / "fits.npz")
    r = subprocess.run([sys.executable, "-m", "wearbench.cli", "identify", str(session), "--ensembles", str(fits)],
                       capture_output=True, text=True, timeout=300, check=False)
    assert r.returncode == 0, r.stderr
    rows = [line for line in r.stdout.splitlines() if line.lstrip("│ ").startswith("s ")]
    assert rows and all("…" not in line for line in r.stdout.splitlines()), r.stdout
    verdicts = ("undecided", "none of the candidates", "the features cannot tell", *(s.name for s in testbed.states))
    assert any(v in rows[0] for v in verdicts)
    assert max(len(line) for line in r.stdout.splitlines()) > 80  # laid out in full, not cut
    r = subprocess.run([sys.executable, "-m", "wearbench.cli", "ensemble", "ninebar-testbed", "--realisations", "4",
                        "--cycles", "2", "--workers", "0", "--out", str(tmp_path / "e.npz")],
                       capture_output=True, text=True, timeout=900, check=False)
    assert r.returncode == 0, r.stderr
    lines = [x for x in r.stderr.splitlines() if x.startswith("theory ensembles")]
    assert lines[0].startswith("theory ensembles: 16 realisations, about") and "of CPU" in lines[0]  # said first
    lines = lines[1:]
    assert lines[0].startswith("theory ensembles: started") and lines[-1].startswith("theory ensembles: 16/16")
    assert 3 <= len(lines) <= 12, lines  # a line per tenth, not one per redraw
