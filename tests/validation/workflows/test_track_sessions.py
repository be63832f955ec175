"""`wearbench record --cycles-run N` stores the cycles a bench had run in the session, and `track`
reads them when no --cycles-run is given (a command-line value wins, with a note where it differs)."""

from __future__ import annotations

import json

import pytest
from wearbench.bench.load import shipped_bench
from wearbench.cli import main
from wearbench.validation.measurement.features import FeatureSpec
from wearbench.validation.measurement.session import load_session
from wearbench.validation.workflows import measure, session_set

from ...acquisition.conftest import FAST, HARMONIC


def _record(tmp_path, name: str, *extra: str):
    config = tmp_path / "emulator.json"
    config.write_text(json.dumps(HARMONIC))
    out = tmp_path / name
    assert main(["record", str(shipped_bench("ninebar-testbed")), "--backend", "sim", "--option", "speedup=inf",
                 "--option", f"config={config}", "--speed", f"{FAST}", "--cycles", "2", "--out", str(out),
                 *extra]) == 0
    return out


@pytest.fixture(scope="module")
def sessions(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("life")
    return (_record(tmp, "s0.mcap", "--cycles-run", "0"), _record(tmp, "s1.mcap", "--cycles-run", "150_000"),
            _record(tmp, "plain.mcap"))


def test_record_stores_the_cycles_run_and_track_reads_them(sessions, tmp_path, monkeypatch, capsys):
    s0, s1, plain = sessions
    assert measure.recorded_cycles_run(load_session(s0)) == 0.0
    assert measure.recorded_cycles_run(load_session(s1)) == 150_000.0
    assert measure.recorded_cycles_run(load_session(plain)) is None
    seen = []

    class Fitted:  # what track needs of the estimator here: its feature spec, its file (none: no stored move)
        spec = FeatureSpec()
        path = None
        about = None

    def fake_track(features, cycles_run, model, **kw):
        from wearbench.validation.estimation.estimate import Interval
        from wearbench.validation.estimation.track import Track

        seen.append(list(cycles_run))
        i = Interval(1.0, 1.0, 1.0, 1.0, 1.0)
        return Track(sessions=kw["labels"], cycles_run=list(cycles_run), depth=[i] * len(cycles_run), clearance=i,
                     factor=i, coefficient=i, cycles_to_limit=None, limit=None, beyond=0.0, notes=[])

    monkeypatch.setattr(measure, "track_features", fake_track)
    monkeypatch.setattr(session_set, "build_estimator", lambda *a, **k: Fitted())
    monkeypatch.setattr(measure, "fit_estimator", lambda *a, **k: None)
    t = measure.track_sessions([s0, s1], calibration=None)
    assert seen[-1] == [0.0, 150_000.0] and t.notes == []
    t = measure.track_sessions([s0, s1], [0.0, 200_000.0], calibration=None)
    assert seen[-1] == [0.0, 200_000.0]
    assert t.notes == ["s1: cycles run 200,000 as given, 150,000 as recorded in the session"]
    with pytest.raises(ValueError, match="session plain: no cycles run recorded in it"):
        measure.track_sessions([s0, plain], calibration=None)
    capsys.readouterr()
    assert main(["track", str(s0), str(s1), "--calibration", "none"]) == 0
    assert seen[-1] == [0.0, 150_000.0] and "s1: 150,000 cycles run" in capsys.readouterr().out


@pytest.mark.parametrize("value", ["-5", "lots", "nan", "inf"])
def test_a_nonsense_cycles_run_is_refused_before_recording(tmp_path, capsys, value):
    out = tmp_path / "s.mcap"
    assert main(["record", "ninebar-testbed", "--backend", "sim", "--cycles", "2", "--out", str(out),
                 "--cycles-run", value]) == 2
    err = capsys.readouterr().err
    assert f"--cycles-run {value!r}" in err and "a finite number >= 0" in err and not out.exists()


@pytest.mark.parametrize("extra, says", [
    (["--cycles-run", "0,nan"], ("--cycles-run 'nan': expected the cycles the bench had run before the session, "
                                 "a finite number >= 0")),
    (["--cycles-run", "0,-5"], "--cycles-run '-5'"),
    (["--limit", "0"], "--limit '0': expected a finite length > 0"),
    (["--limit", "-1mm"], "--limit '-1mm': expected a finite length > 0"),
    (["--figure", "life.txt"], "--figure life.txt: a figure needs one of the suffixes"),
])
def test_track_refuses_bad_values_before_any_work(sessions, tmp_path, monkeypatch, capsys, extra, says):
    """Each bad value is one line naming the option and value, exit 2, before the estimator is built."""
    s0, s1, _ = sessions
    monkeypatch.setattr(session_set, "build_estimator", lambda *a, **k: pytest.fail("built an estimator"))
    monkeypatch.chdir(tmp_path)
    assert main(["track", str(s0), str(s1), "--calibration", "none", *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert says in err and len(err.splitlines()) == 1, err


def test_track_takes_each_recording_once_and_never_back_in_time(sessions, monkeypatch, capsys):
    """The same file twice is one session, not a life; cycles run that go back in time against the
    sessions' recorded starts are refused, naming both sessions."""
    s0, s1, _ = sessions
    monkeypatch.setattr(session_set, "build_estimator", lambda *a, **k: pytest.fail("built an estimator"))
    assert main(["track", str(s0), str(s0), "--cycles-run", "0,200000", "--calibration", "none"]) == 2
    assert "session s0 #2: the same recording as s0; tracking takes each session once" in capsys.readouterr().err
    a, b = load_session(s0), load_session(s1)
    a.metadata["session"]["started_at"], b.metadata["session"]["started_at"] = "2026-11-02T09:00:00Z", \
        "2026-11-09T09:00:00Z"
    measure.check_life_order([a, b], [0.0, 2e5])  # in order
    with pytest.raises(ValueError, match=r"session s1: recorded after s0 \(2026-11-09 09:00 after 2026-11-02 "
                                         r"09:00\) with fewer cycles run \(0 < 200,000\); a bench does not unwear"):
        measure.check_life_order([a, b], [2e5, 0.0])
    b.metadata["session"].pop("started_at")
    measure.check_life_order([a, b], [2e5, 0.0])  # a session that does not say when: nothing to check against
