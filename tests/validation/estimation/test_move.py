"""The benches' move from new to worn stored beside the estimator it was measured against: saved and
loaded with it, used by ``track`` by default (a planted move recovered; without it the factor comes
out low), refused with another estimator, and measured and stored end to end by
``wearbench estimator --lives`` on a tiny design."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from wearbench.cli import main
from wearbench.validation.estimation.estimate import load_estimator, save_estimator
from wearbench.validation.estimation.move import (
    Move,
    life_move,
    load_move,
    move_path,
    save_move,
    stored_move,
)
from wearbench.validation.estimation.track import track_features
from wearbench.validation.measurement.features import CycleFeatures

from ...acquisition.conftest import FAST
from ..workflows import test_track_sessions
from . import test_estimate
from .test_estimate import SB, SPEC, SW, P, true_mean

model = test_estimate.model  # the synthetic estimator (a fixture)
sessions = test_track_sessions.sessions  # two recorded sessions, at 0 and 150k cycles run (a fixture)

C, RUNS = 0.4e-3, np.array([0.0, 1e5, 2e5])


def planted(model, rng) -> tuple[np.ndarray, list]:
    """A move m (a third of the change from new to 260k effective cycles, against it, plus a random
    part) and 12 lives of a bench worn 1.3x the file's whose worn sessions sit m off the true mean."""
    m = -0.35 * (true_mean(C, 2.6e5) - true_mean(C, 0.0)) + rng.normal(0.0, 0.05, P)
    lives = []
    for _ in range(12):
        offset = rng.normal(0.0, np.sqrt(SB), P)
        xbars = np.stack([true_mean(C, 1.3 * n) + offset + (n > 0) * m + rng.normal(0.0, np.sqrt(SW / 20), P)
                          for n in RUNS])
        lives.append((xbars, RUNS, C, 1.3))
    return m, lives


def two_sessions(m) -> list[CycleFeatures]:
    """Sessions at 0 and 200k of a bench worn 1.3x the file's, their cycle means the true mean plus m."""
    return [CycleFeatures(SPEC, np.repeat((true_mean(C, 1.3 * n) + (n > 0) * m)[None], 20, axis=0), np.zeros(20))
            for n in (0.0, 2e5)]


def test_a_planted_move_is_measured_to_its_standard_error_and_track_given_it_recovers_the_factor(model):
    """life_move measures the planted m plus the estimator's own error of the change from new (true less
    emulated mean) to its standard error, and says that error; two sessions (0 and 200k) of a bench worn
    1.3x the file's, their cycle means exactly the model's plus m, give a factor well below 1.3 without
    the move and 1.3 with it."""
    m, lives = planted(model, np.random.default_rng(13))
    move = life_move(model, lives)
    se = np.sqrt((SW / 20 + SW / 40) / 12)  # the new session's and the two worn sessions' noise, over 12 lives
    error = lambda n: true_mean(C, n) - model.mean(C, n)
    target = m + np.mean([error(1.3 * n) for n in RUNS[1:]], axis=0) - error(0.0)
    assert np.sqrt(np.mean((move.mean - target) ** 2)) == pytest.approx(se, rel=0.35)
    assert np.sqrt(np.median(np.diag(move.covariance))) == pytest.approx(se, rel=0.35)
    plain = track_features(two_sessions(m), [0.0, 2e5], model, coefficient=5.2e-14)
    moved = track_features(two_sessions(m), [0.0, 2e5], model, coefficient=5.2e-14, move=move)
    assert plain.factor.median < 1.0 and not plain.factor.contains(1.3, 50)
    assert moved.factor.median == pytest.approx(1.3, abs=0.1) and moved.factor.contains(1.3, 50)
    with pytest.raises(ValueError, match="drift=False"):
        track_features(two_sessions(m), [0.0, 2e5], model, coefficient=5.2e-14, move=move, drift=False)
    with pytest.raises(ValueError, match="a session at 0"):
        life_move(model, [(lives[0][0][1:], RUNS[1:], C, 1.3)] * 3)
    with pytest.raises(ValueError, match="at least three"):
        life_move(model, lives[:2])
    with pytest.raises(ValueError, match="at least three"):  # six lives of two benches
        life_move(model, lives[:6], benches=[0, 1] * 3)


@pytest.mark.slow
def test_a_move_stored_beside_its_estimator_is_loaded_with_it_and_track_uses_it(model, tmp_path):
    m, lives = planted(model, np.random.default_rng(13))
    about = {"sensor_paths": ["default path"], "seeds": list(range(500, 512)), "factor": 1.3,
             "sessions": list(RUNS), "cycles": 20}
    measured = life_move(model, lives, about)
    path = save_estimator(model.estimator, tmp_path / "bench.npz")
    save_move(measured, move_path(path))
    assert move_path(path) == tmp_path / "bench.move.npz"
    est = load_estimator(path)
    assert est.path == path
    stored = stored_move(est)
    assert stored.estimator == est.key and stored.path == str(move_path(path))
    assert stored.about == {"bench": "synthetic", **about, "benches": 12}
    assert np.array_equal(stored.mean, measured.mean) and np.array_equal(stored.covariance, measured.covariance)
    assert stored.rows.shape == (12, P)
    assert "12 simulated lives (default path; seeds 500-511; wear factor 1.3" in stored.describe()
    # lives of one bench through two sensor paths count once in the move's error, not twice
    twice = life_move(model, lives + lives, about, benches=list(range(12)) * 2)
    assert np.allclose(twice.mean, measured.mean) and np.allclose(twice.covariance, measured.covariance)
    assert twice.rows.shape == (24, P) and "24 simulated lives of 12 benches" in twice.describe()

    plain = track_features(two_sessions(m), [0.0, 2e5], model, coefficient=5.2e-14)
    moved = track_features(two_sessions(m), [0.0, 2e5], model, coefficient=5.2e-14, move=stored)
    direct = track_features(two_sessions(m), [0.0, 2e5], model, coefficient=5.2e-14, move=measured)
    assert moved.factor == direct.factor and plain.factor.median < 1.0 < moved.factor.median
    assert plain.move is None and moved.move["lives"] == 12 and moved.move["file"] == str(move_path(path))
    said = lambda t: any("no measured move from new to worn" in note for note in t.notes)
    assert said(plain) and not said(moved)
    assert json.loads(json.dumps(moved.to_dict()))["move"]["seeds"] == about["seeds"]
    # an estimator without a file beside it, or without a move there, has none
    assert stored_move(model.estimator) is None
    save_estimator(model.estimator, tmp_path / "alone.npz")
    assert stored_move(load_estimator(tmp_path / "alone.npz")) is None


def test_a_move_measured_against_another_estimator_is_refused_naming_file_field_and_value(model, tmp_path):
    _, lives = planted(model, np.random.default_rng(14))
    path = save_estimator(model.estimator, tmp_path / "bench.npz")
    other = life_move(model, lives)
    save_move(Move(other.mean, other.covariance, "0123abcd", other.rows), move_path(path))
    est = load_estimator(path)
    with pytest.raises(ValueError) as exc:
        stored_move(est)
    text = str(exc.value)
    assert str(move_path(path)) in text and "another estimator (key 0123abcd)" in text and f"key {est.key}" in text
    with pytest.raises(ValueError, match=r"another estimator \(key 0123abcd\)"):
        load_move(move_path(path), est.key)
    np.savez(move_path(path), mean=other.mean)  # an .npz that is not a move
    with pytest.raises(ValueError, match=r"bench.move.npz: not a move \('wearbench estimator --lives'\) \(no 'about'"):
        stored_move(est)
    save_estimator(est, move_path(path))  # another kind of artefact
    with pytest.raises(ValueError, match=r"bench.move.npz is an estimator, not a move"):
        stored_move(est)
    with pytest.raises(ValueError, match="features"):  # a move of another feature set
        track_features(two_sessions(np.zeros(P)), [0.0, 2e5], model, coefficient=5.2e-14,
                       move=Move(other.mean[:5], other.covariance[:5, :5], est.key, other.rows[:, :5]))


@pytest.mark.slow
def test_track_uses_the_stored_move_unless_told_not_to(model, sessions, tmp_path, capsys):
    """`wearbench track --estimator FILE` with FILE.move.npz beside it: the move is used and said (output,
    --json), --no-move leaves it out and says so; a move of another estimator stops track with its error.
    The synthetic estimator explains nothing of these emulated sessions: track says so (exit 1, no wear
    factor printed) and still says which move it used."""
    s0, s1, _ = sessions
    _, lives = planted(model, np.random.default_rng(15))
    # the estimator at the sessions' speed: one of another speed is refused (below)
    path = save_estimator(replace(model.estimator, speed=FAST), tmp_path / "bench.npz")
    save_move(life_move(model, lives, {"sensor_paths": ["default path"], "seeds": [1, 2], "factor": 1.3}),
              move_path(path))
    common = ["track", str(s0), str(s1), "--estimator", str(path), "--calibration", "none"]
    capsys.readouterr()
    assert main([*common, "--json", str(tmp_path / "with.json")]) == 1
    out = capsys.readouterr().out
    assert out.startswith("no (c, k) explains these sessions") and "1/Pa" not in out  # no factor printed
    assert "move from new to worn measured on 12 simulated lives (default path; seeds 1-2" in out
    assert "no measured move" not in out
    with_move = json.loads((tmp_path / "with.json").read_text())
    assert with_move["move"]["file"] == str(move_path(path)) and with_move["move"]["lives"] == 12
    assert main([*common, "--no-move", "--json", str(tmp_path / "without.json")]) == 1
    out = capsys.readouterr().out
    assert "no measured move from new to worn used (--no-move)" in out
    without = json.loads((tmp_path / "without.json").read_text())
    assert without["move"] is None and without["factor"] != with_move["factor"]
    save_move(Move(np.zeros(P), np.eye(P), "0123abcd", np.zeros((3, P))), move_path(path))
    assert main(common) == 2
    assert "another estimator (key 0123abcd)" in capsys.readouterr().err
    slow = save_estimator(model.estimator, tmp_path / "slow.npz")  # built at 2 pi rad/s
    assert main(["track", str(s0), str(s1), "--estimator", str(slow), "--calibration", "none"]) == 2
    assert f"{slow}: an estimator built at 6.28319 rad/s; session s0 commanded at {FAST:.6g} rad/s" in \
        capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.timeout(1800)
def test_the_estimator_command_measures_and_stores_the_move_on_simulated_lives(tmp_path, monkeypatch, capsys):
    """A tiny design (2 clearances x 0 and 200k cycles, 3 realisations of 2 cycles) and 3 lives of 1
    cycle per session, in this process: the move is stored beside the estimator, keyed to it and saying
    what it was measured on; a second run keeps the estimator and refuses the existing move."""
    monkeypatch.setenv("WEARBENCH_CACHE", str(tmp_path / "cache"))
    out = tmp_path / "tiny.npz"
    args = ["estimator", "ninebar-testbed", "--design-clearances", "0.3mm,0.5mm", "--design-cycles", "0,200000",
            "--realisations", "3", "--ensemble-cycles", "2", "--out", str(out), "--workers", "0",
            "--lives", "3", "--life-cycles", "1", "--life-seed", "700"]
    assert main(args) == 0
    text = capsys.readouterr().out
    est = load_estimator(out)
    move = stored_move(est)
    assert move.estimator == est.key and move.rows.shape == (3, est.features.shape[-1])
    assert move.about["seeds"] == [700, 701, 702] and move.about["factor"] == 1.3
    assert move.about["sessions"] == pytest.approx([0.0, 2e5 / 6, 4e5 / 6, 6e5 / 6, 8e5 / 6])
    assert all(0.3e-3 + 0.2e-3 / 8 <= c <= 0.5e-3 - 0.2e-3 / 4 for c in move.about["clearances"])
    assert np.all(np.isfinite(move.mean)) and np.all(np.linalg.eigvalsh(move.covariance) > -1e-12)
    knots = move.rate.clearances  # the features' rate against clearance, measured on the same lives
    assert (knots[0], knots[-1]) == (min(move.about["clearances"]), max(move.about["clearances"]))
    assert f"saved: {move_path(out)}" in text
    before = out.stat().st_mtime_ns
    assert main(args) == 2  # the move exists: refused, the estimator kept as it was
    assert "tiny.move.npz" in capsys.readouterr().err and out.stat().st_mtime_ns == before


def test_the_shipped_move_belongs_to_the_shipped_estimator():
    """The test bed's move ships beside its estimator (in the wheel: validation/inference/shipped/estimator/*.npz), keyed to
    that file's key; rebuilding the estimator means measuring the move again (README, track)."""
    from wearbench.bench.load import load_bench, shipped_bench
    from wearbench.validation.inference.artefacts import shipped_path

    est = load_estimator(shipped_path("estimator", load_bench(shipped_bench("ninebar-testbed")).name))
    move = stored_move(est)
    assert move is not None and move.estimator == est.key and move.mean.shape == (est.features.shape[-1],)
    assert move.about["factor"] == 1.3 and move.about["benches"] >= 20
    assert move.rate is not None and move.rate.clearances[0] == min(move.about["clearances"])
