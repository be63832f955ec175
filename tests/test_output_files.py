"""The one output-file policy (``wearbench.bench.output_file``), command by command: nothing a user
types replaces an existing file without --force, nothing writes over a recorded session, and a
command that fails or is interrupted leaves the old file exactly as it was."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from wearbench.acquisition.session_file import read_session
from wearbench.bench.load import shipped_bench
from wearbench.bench.output_file import check_output, output_file, output_folder, save_npz
from wearbench.cli import main

from .acquisition.conftest import FAST, HARMONIC

OLD = b"results of yesterday"


def _session(tmp_path, name="s.mcap", cycles="2"):
    """A short finished session (sim backend, as fast as the host can)."""
    config = tmp_path / "emulator.json"
    config.write_text(json.dumps(HARMONIC))
    out = tmp_path / name
    assert main(["record", str(shipped_bench("ninebar-testbed")), "--backend", "sim", "--option", "speedup=inf",
                 "--option", f"config={config}", "--speed", f"{FAST}", "--cycles", cycles, "--out", str(out)]) == 0
    return out


def _one_line(capsys) -> str:
    err = "".join(x for x in capsys.readouterr().err.splitlines(True) if not x.startswith("compiling"))
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err


def test_the_policy(tmp_path, capsys):
    old = tmp_path / "r.json"
    old.write_bytes(OLD)
    with pytest.raises(FileExistsError, match="--force"):
        check_output(old)
    with pytest.raises(RuntimeError), output_file(old, force=True) as tmp:  # a failure half way
        tmp.write_text("half")
        raise RuntimeError("disk gone")
    assert old.read_bytes() == OLD and sorted(p.name for p in tmp_path.iterdir()) == ["r.json"]
    with output_file(old, force=True) as tmp:
        assert old.read_bytes() == OLD  # untouched while the new one is written
        tmp.write_text("new")
    assert old.read_text() == "new" and sorted(p.name for p in tmp_path.iterdir()) == ["r.json"]
    session = tmp_path / "s.mcap"
    session.write_bytes(b"\x89MCAP0\r\n and the rest of a session")
    for kwargs in ({}, {"force": True}, {"force": True, "folder": True}):
        with pytest.raises(FileExistsError, match="holds a recorded MCAP session"):
            check_output(session, **kwargs)
    with output_file(session, force=True, session=True) as tmp:
        tmp.write_bytes(b"\x89MCAP0\r\n another session")
    assert "replaced the session" in capsys.readouterr().err  # said, not silent
    folder = tmp_path / "report"
    folder.mkdir()
    (folder / "report.html").write_text("old report")
    (folder / "notes.txt").write_text("mine")
    with pytest.raises(FileExistsError, match="folder with files"):
        check_output(folder, folder=True)
    with pytest.raises(KeyboardInterrupt), output_folder(folder, force=True) as tmp:
        (tmp / "report.html").write_text("new report")
        raise KeyboardInterrupt
    assert (folder / "report.html").read_text() == "old report"
    with output_folder(folder, force=True) as tmp:
        (tmp / "report.html").write_text("new report")
    assert (folder / "report.html").read_text() == "new report" and (folder / "notes.txt").read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.json", "report", "s.mcap"]


def test_save_npz_writes_any_name_whole_or_not_at_all(tmp_path):
    """The program's own .npz files (ensembles, estimator, move) go through a temporary name renamed
    when complete, whatever the name's suffix (``--out ens`` as well as ``ens.npz``, and the
    ``output_file`` temporary name it is given); a failure half way leaves the old file and nothing
    beside it."""
    for name in ("ens.npz", "ens", "ens.bin"):
        path = save_npz(tmp_path / name, a=np.arange(3))
        assert path == tmp_path / name and np.load(path)["a"].tolist() == [0, 1, 2]
    with output_file(tmp_path / "ens", force=True) as tmp:
        save_npz(tmp, a=np.arange(4))
    assert np.load(tmp_path / "ens")["a"].tolist() == [0, 1, 2, 3]
    with pytest.raises(TypeError):
        save_npz(tmp_path / "ens", a=np.arange(2), b=object.__new__(_Unpicklable))
    assert np.load(tmp_path / "ens")["a"].tolist() == [0, 1, 2, 3]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ens", "ens.bin", "ens.npz"]


class _Unpicklable:
    def __reduce__(self):
        raise TypeError("not an array")


def test_recover_never_replaces_a_file_and_a_failure_leaves_it_whole(tmp_path, capsys):
    """Issue 25, item 1: `recover X --out EXISTING` replaced the file and, failing on another tool's
    MCAP, left it cut to 59 bytes after a KeyError traceback."""
    from mcap.writer import Writer

    session = _session(tmp_path)
    keep = tmp_path / "keep.mcap"
    keep.write_bytes(session.read_bytes())
    capsys.readouterr()
    assert main(["recover", str(session), "--out", str(keep)]) == 2
    assert "already exists" in _one_line(capsys) and keep.read_bytes() == session.read_bytes()
    foreign = tmp_path / "foreign.mcap"  # another tool's JSON on a session topic
    with open(foreign, "wb") as fh:
        w = Writer(fh)
        w.start()
        sid = w.register_schema("Accel", "jsonschema", b"{}")
        cid = w.register_channel("/acceleration", "json", sid)
        w.add_message(cid, 1, b'{"x": 1.0}', 1)
        w.finish()
    assert main(["recover", str(foreign), "--out", str(keep), "--force"]) == 2
    err = _one_line(capsys)
    assert str(foreign) in err and "not a wearbench session message" in err
    assert keep.read_bytes() == session.read_bytes()  # whole, not cut
    assert main(["recover", str(session), "--out", str(keep), "--force"]) == 0
    assert "replaced the session" in capsys.readouterr().err and read_session(keep).finished


def test_no_command_writes_over_a_session(tmp_path, capsys):
    """Issue 25, item 2: `identify --json s1.mcap s2.mcap` wrote JSON over s1.mcap; `ensemble --out
    session.mcap` wrote an .npz over it. Now refused before any work, with or without --force."""
    session = _session(tmp_path)
    before = session.read_bytes()
    capsys.readouterr()
    for args in (["identify", "--json", str(session), str(session)],
                 ["identify", str(session), "--json", str(session), "--force"],
                 ["ensemble", "ninebar-testbed", "--out", str(session), "--force"],
                 ["simulate", "slider-crank", "--out", str(session), "--force"],
                 ["sweep", "slider-crank", "--vary", "clearance=0.2mm", "--out", str(session), "--force"],
                 ["wear", "slider-crank", "--out", str(session)],
                 ["study", "ninebar", "--quick", "--out", str(session), "--force"]):
        assert main(args) == 2, args
        err = _one_line(capsys)
        assert str(session) in err and "holds a recorded MCAP session" in err, (args, err)
    assert session.read_bytes() == before


def test_an_existing_result_needs_force(tmp_path, capsys):
    out = tmp_path / "run.csv"
    out.write_bytes(OLD)
    args = ["simulate", "slider-crank", "--revolutions", "0.2", "--output-rate", "2kHz", "--out", str(out)]
    assert main(args) == 2
    assert "--force" in _one_line(capsys) and out.read_bytes() == OLD
    assert main([*args, "--force"]) == 0
    assert out.read_text().startswith("t,")


def test_ctrl_c_during_a_forced_recording_keeps_the_good_session(tmp_path):
    """Issue 25, item 3: Ctrl-C during `record --force` replaced a completed session with the
    interrupted one. The old file stays until the new session completes its target; the interrupted
    one is left beside it, finished and readable."""
    out = _session(tmp_path)
    before = out.read_bytes()
    config = tmp_path / "emulator.json"
    proc = subprocess.Popen([sys.executable, "-m", "wearbench.cli", "record", str(shipped_bench("ninebar-testbed")),
                             "--backend", "sim", "--option", "speedup=1", "--option", f"config={config}",
                             "--speed", f"{FAST}", "--cycles", "500", "--out", str(out), "--force"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    new = tmp_path / "s.mcap.new"
    deadline = time.monotonic() + 120
    while not (new.exists() and new.stat().st_size > 20_000) and time.monotonic() < deadline:
        time.sleep(0.2)
    time.sleep(1.0)
    proc.send_signal(signal.SIGINT)
    _stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    assert out.read_bytes() == before  # the good session, byte for byte
    assert f"{out} kept as it was: the new session did not complete" in stderr and "Traceback" not in stderr
    interrupted = read_session(new)
    assert interrupted.finished and interrupted.metadata["result"]["reason"].startswith("interrupted")
    assert not any(p.name.endswith((".lock", ".ballast")) for p in tmp_path.iterdir()), os.listdir(tmp_path)


# ---- the commands added beside the policy: estimate, estimator, track, calibrate, compare, demo, emulate ----

@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """A short finished session of the test bed, shared by the cases below (none writes it)."""
    return _session(tmp_path_factory.mktemp("session"))


@pytest.fixture(scope="module")
def synthetic():
    """A small fitted estimator on synthetic design features (``validation/test_estimate.py``), an
    estimate of one session and a track of two: real results to write, in a second."""
    from wearbench.validation.estimation.estimate import Estimator, estimate_features, fit_estimator
    from wearbench.validation.estimation.track import track_features

    from .validation.estimation.test_estimate import DESIGN, OPTIONS, draw, session, true_mean

    rng = np.random.default_rng(0)
    feats = np.stack([np.stack([draw(rng, true_mean(c, n), 16, 8) for n in DESIGN.cycles])
                      for c in DESIGN.clearances])
    est = Estimator("synthetic", "k", DESIGN, feats, np.outer(np.ones(5), np.array(DESIGN.cycles) * 2e-11), 2 * np.pi)
    model = fit_estimator(est, OPTIONS)
    estimates = [estimate_features(session(rng, 0.4e-3, n), model) for n in (1e5, 3e5)]
    track = track_features([session(rng, 0.4e-3, n) for n in (0.0, 3e5)], [0.0, 3e5], model, coefficient=5.2e-14)
    return est, estimates, track


def _left(folder) -> list[str]:
    """The names in ``folder`` but the per-test result cache (``conftest.py``)."""
    return sorted(p.name for p in folder.iterdir() if p.name != "wearbench-cache")


class _Interrupted(dict):
    """A JSON object whose encoding is cut by a Ctrl-C half way through a file."""

    def items(self):
        raise KeyboardInterrupt


def _calibration_key(session) -> str:
    from wearbench.validation.inference.calibration import calibration_key
    from wearbench.validation.measurement.scaling import resolve_analysis
    from wearbench.validation.measurement.session import load_session

    s = load_session(session)  # calibrate's features: the bench's own at the session's speed
    return calibration_key(s.bench, s.metadata, resolve_analysis(s.bench, s.commanded_speed).features)


def test_the_new_commands_never_write_over_a_session(recorded, capsys):
    """estimate/track --json (a file, like identify's), estimate/compare/demo --out, estimator --out and
    emulate --sent-log (appended to: bytes after a footer would break the session): refused, with or
    without --force, before any work."""
    s = str(recorded)
    before = recorded.read_bytes()
    capsys.readouterr()
    for args in (["estimate", s, "--json", s, "--force"], ["estimate", s, "--out", s, "--force"],
                 ["estimator", "ninebar-testbed", "--out", s, "--force"],
                 ["track", s, "--cycles-run", "0", "--json", s, "--force"],
                 ["track", s, "--cycles-run", "0", "--figure", s, "--force"],
                 ["compare", s, "--out", s, "--force"], ["demo", "--out", s, "--force"],
                 ["emulate", "ninebar-testbed", "--serial", "--sent-log", s]):
        assert main(args) == 2, args
        err = _one_line(capsys)
        assert s in err and "holds a recorded MCAP session" in err, (args, err)
    assert recorded.read_bytes() == before


def test_an_existing_result_is_refused_before_the_work(recorded, tmp_path, capsys):
    """Every command refuses an existing file (or a folder with files) without --force, with the one
    message, before it builds an estimator or ensembles; the file is left byte for byte."""
    s = str(recorded)
    old = tmp_path / "old.json"
    old.write_bytes(OLD)
    folder = tmp_path / "figures"
    folder.mkdir()
    (folder / "posterior_session.png").write_bytes(OLD)
    calibrations = tmp_path / "calibrations"
    calibrations.mkdir()
    stored = calibrations / f"{_calibration_key(recorded)}.json"
    stored.write_bytes(OLD)
    capsys.readouterr()
    for args, message in (
            (["estimate", s, "--json", str(old)], f"--json {old}: a file already exists"),
            (["estimate", s, "--out", str(folder)], f"--out {folder}: a folder with files"),
            (["estimator", "ninebar-testbed", "--out", str(old)], f"--out {old}: a file already exists"),
            (["track", s, "--cycles-run", "0", "--json", str(old)], f"--json {old}: a file already exists"),
            (["track", s, "--cycles-run", "0", "--figure", str(old)], f"--figure {old}: a file already exists"),
            (["compare", s, "--out", str(folder)], f"--out {folder}: a folder with files"),
            (["demo", "--out", str(folder)], f"--out {folder}: a folder with files"),
            (["calibrate", s, "--state", "0.3 mm new", "--dir", str(calibrations)],
             f"calibration {stored}: a file already exists")):
        assert main(args) == 2, args
        err = _one_line(capsys)
        assert message in err and "--force" in err, (args, err)
    assert old.read_bytes() == OLD and (folder / "posterior_session.png").read_bytes() == OLD
    assert stored.read_bytes() == OLD and sorted(p.name for p in calibrations.iterdir()) == [stored.name]
    assert _left(tmp_path) == ["calibrations", "figures", "old.json"]


def test_estimate_and_track_keep_the_old_files_until_the_new_ones_are_complete(recorded, synthetic, tmp_path,
                                                                                 monkeypatch, capsys):
    """A Ctrl-C half way through writing --json or the figures leaves the old files as they were;
    with --force and no failure they are replaced (other files in an --out folder stay)."""
    import wearbench.reports.track as track_module
    from wearbench.reports import estimate as estimate_figure
    from wearbench.validation.workflows import measure

    _est, estimates, track = synthetic
    s = str(recorded)
    monkeypatch.setattr(measure, "estimate_sessions", lambda *a, **k: estimates)
    monkeypatch.setattr(measure, "track_sessions", lambda *a, **k: track)
    old, figure, folder = tmp_path / "e.json", tmp_path / "life.png", tmp_path / "posterior"
    folder.mkdir()
    for p in (old, figure, folder / "posterior_session.png", folder / "mine.txt"):
        p.write_bytes(OLD)
    real_as_dict, real_figure = type(estimates[0]).to_dict, estimate_figure.posterior_figure

    def half_figure(e, path, *a, **k):  # the first figure is written, then Ctrl-C
        if e is estimates[1]:
            raise KeyboardInterrupt
        return real_figure(e, path, *a, **k)

    def half_track_figure(t, path, **k):
        Path(path).write_bytes(b"\x89PNG half")
        raise KeyboardInterrupt

    with monkeypatch.context() as m:
        m.setattr(type(estimates[0]), "to_dict", lambda e: _Interrupted(cut=1) if e is estimates[1] else real_as_dict(e))
        m.setattr(estimate_figure, "posterior_figure", half_figure)
        m.setattr(track_module, "track_figure", half_track_figure)
        assert main(["estimate", s, s, "--json", str(old), "--force"]) == 130
        assert main(["estimate", s, s, "--out", str(folder), "--force"]) == 130
        assert main(["track", s, s, "--cycles-run", "0,300000", "--figure", str(figure), "--force"]) == 130
    for p in (old, figure, folder / "posterior_session.png", folder / "mine.txt"):
        assert p.read_bytes() == OLD, p
    assert _left(tmp_path) == ["e.json", "life.png", "posterior"]
    assert sorted(p.name for p in folder.iterdir()) == ["mine.txt", "posterior_session.png"]
    capsys.readouterr()
    assert main(["estimate", s, s, "--json", str(old), "--out", str(folder), "--force"]) == 0
    rows = json.loads(old.read_text())
    assert [r["clearance"]["median"] for r in rows] == [e.clearance.median for e in estimates]
    assert (folder / "posterior_session_2.png").read_bytes()[:4] == b"\x89PNG" and (folder / "mine.txt").read_bytes() == OLD
    assert f"figure: {folder / 'posterior_session.png'}" in capsys.readouterr().out
    assert main(["track", s, s, "--cycles-run", "0,300000", "--json", str(old), "--figure", str(figure),
                 "--force"]) == 0
    assert json.loads(old.read_text())["factor"] and figure.read_bytes()[:4] == b"\x89PNG"


def test_estimator_replaces_its_file_only_with_force_and_only_complete(synthetic, tmp_path, monkeypatch, capsys):
    """`estimator` had its own --replace: now the one --force, and a failure while saving keeps the old file."""
    from wearbench.validation.estimation import estimate

    est = synthetic[0]
    out = tmp_path / "bed-estimator.npz"
    out.write_bytes(OLD)
    monkeypatch.setattr(estimate, "build_estimator", lambda *a, **k: est)
    real_save = estimate.save_estimator

    def half_save(e, path):
        Path(path).write_bytes(b"PK half an npz")
        raise OSError(28, "No space left on device")

    args = ["estimator", "ninebar-testbed", "--out", str(out)]
    with pytest.raises(SystemExit):
        main([*args, "--replace"])  # the old switch is gone: one switch name across commands
    capsys.readouterr()
    assert main(args) == 2 and "--force" in _one_line(capsys)
    monkeypatch.setattr(estimate, "save_estimator", half_save)
    assert main([*args, "--force"]) == 2 and "No space left" in _one_line(capsys)
    assert out.read_bytes() == OLD and _left(tmp_path) == [out.name]
    monkeypatch.setattr(estimate, "save_estimator", real_save)
    assert main([*args, "--force"]) == 0
    assert estimate.load_estimator(out).features.shape == est.features.shape


def test_compare_writes_its_report_folder_under_the_policy(recorded, tmp_path, monkeypatch, capsys):
    """`compare --out DIR` (default report/): a folder with files in it is refused without --force; a
    report cut half way keeps the old one; with --force its files are replaced and others stay."""
    from wearbench.reports import assessment
    from wearbench.reports.comparison import ComparisonReport
    from wearbench.validation.workflows import assess

    out = tmp_path / "report"
    out.mkdir()
    (out / "report.html").write_bytes(OLD)
    (out / "notes.txt").write_bytes(OLD)
    monkeypatch.setattr(assess, "assess_sessions", lambda *a, **k: [])

    def report(half: bool):
        def write(assessed, folder, **k):
            (folder / "report.html").write_text("new report")
            if half:
                raise KeyboardInterrupt
            (folder / "scores.json").write_text("{}")
            return ComparisonReport([], folder, folder / "report.html", folder / "scores.json")
        return write

    args = ["compare", str(recorded), "--out", str(out)]
    monkeypatch.setattr(assessment, "write_assessment_report", report(half=True))
    assert main(args) == 2 and "--force" in _one_line(capsys)
    assert main([*args, "--force"]) == 130
    assert (out / "report.html").read_bytes() == OLD and sorted(p.name for p in out.iterdir()) == [
        "notes.txt", "report.html"]
    monkeypatch.setattr(assessment, "write_assessment_report", report(half=False))
    capsys.readouterr()
    assert main([*args, "--force"]) == 0
    assert f"report: {out / 'report.html'}  scores: {out / 'scores.json'}" in capsys.readouterr().out
    assert (out / "report.html").read_text() == "new report" and (out / "notes.txt").read_bytes() == OLD
    assert _left(tmp_path) == ["report"]


def test_the_demo_reruns_into_its_own_folder_and_nowhere_else(recorded, tmp_path):
    """The demo marks its folder: a rerun replaces its sessions and report there; a folder with files the
    demo did not mark needs --force, and even then a session at one of the demo's names stays."""
    from wearbench.cli.demo import MARK, claim_folder

    out = tmp_path / "demo"
    sessions = [out / "sessions" / "a.mcap", out / "sessions" / "b.mcap"]
    assert claim_folder(out, sessions, out / "report", force=False) is False  # new: nothing to replace
    assert (out / MARK).is_file()
    sessions[0].parent.mkdir()
    sessions[0].write_bytes(recorded.read_bytes())  # the demo's own session of the first run
    (out / "report").mkdir()
    (out / "report" / "report.html").write_text("first run")
    assert claim_folder(out, sessions, out / "report", force=False) is True  # a rerun: its files replaced
    mine = tmp_path / "mine"
    (mine / "sessions").mkdir(parents=True)
    (mine / "sessions" / "a.mcap").write_bytes(recorded.read_bytes())  # a recording the demo did not make
    with pytest.raises(FileExistsError, match="a folder with files in it exists"):
        claim_folder(mine, [mine / "sessions" / "a.mcap"], mine / "report", force=False)
    with pytest.raises(FileExistsError, match="holds a recorded MCAP session"):
        claim_folder(mine, [mine / "sessions" / "a.mcap"], mine / "report", force=True)
    assert not (mine / MARK).exists() and (mine / "sessions" / "a.mcap").read_bytes() == recorded.read_bytes()
    assert claim_folder(mine, [mine / "sessions" / "b.mcap"], mine / "report", force=True) is True
    assert (mine / MARK).is_file()


def test_a_stored_calibration_is_a_user_file(tmp_path):
    """`calibrate` had its own --replace: its store is a user file under the one policy (--force), and a
    failure while writing keeps the stored calibration."""
    from types import SimpleNamespace

    from wearbench.validation.inference.artefacts import About
    from wearbench.validation.inference.calibration import save_calibration

    about = About("calibration", "k" * 64, "b", "", float("nan"), "calibrated")

    stored = tmp_path / f"{'k' * 64}.json"
    stored.write_bytes(OLD)
    with pytest.raises(FileExistsError, match="--force"):
        save_calibration(SimpleNamespace(key="k" * 64, about=about, to_dict=dict), tmp_path)

    def cut():
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        save_calibration(SimpleNamespace(key="k" * 64, about=about, to_dict=cut), tmp_path, force=True)
    assert stored.read_bytes() == OLD and _left(tmp_path) == [stored.name]
    assert save_calibration(SimpleNamespace(key="k" * 64, about=about, to_dict=lambda: {"new": 1}), tmp_path,
                            force=True) == stored
    assert json.loads(stored.read_text())["new"] == 1 and json.loads(stored.read_text())["about"]["kind"] == "calibration"


@pytest.fixture
def read_only(tmp_path):
    """A folder nothing can be written in, root included: a read-only tmpfs (root), else mode 555."""
    import os
    import subprocess

    folder = tmp_path / "read-only"
    folder.mkdir()
    if os.geteuid() == 0:
        done = subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=1m", "tmpfs", str(folder)], capture_output=True,
                              check=False)
        if done.returncode:
            pytest.skip(f"cannot mount a read-only tmpfs: {done.stderr.decode().strip()}")
        yield folder
        subprocess.run(["umount", str(folder)], check=False)
    else:
        folder.chmod(0o555)
        yield folder
        folder.chmod(0o755)


@pytest.mark.parametrize("option, name", [("--json", "e.json"), ("--out", "figures")])
def test_a_place_that_cannot_be_written_is_refused_before_any_work(recorded, read_only, monkeypatch, capsys, option,
                                                                    name):
    """`estimate --json/--out` into a read-only folder: one line naming the option, the path and the
    folder, exit 2, before the estimator is built (it failed after the work, naming a temporary file)."""
    from wearbench.validation.workflows import session_set

    monkeypatch.setattr(session_set, "build_estimator", lambda *a, **k: pytest.fail("built an estimator"))
    target = read_only / name
    assert main(["estimate", str(recorded), option, str(target)]) == 2
    err = _one_line(capsys)
    assert f"{option} {target}: cannot write in {read_only}" in err and ".partial" not in err


def test_a_forced_exit_leaves_nothing_half_written(tmp_path):
    """What the Ctrl-C watchdog's forced exit (os._exit, which runs no finally) calls first: every
    temporary name still being written goes, the old outputs stay."""
    from wearbench.bench.output_file import output_file, output_folder, remove_unfinished

    old = tmp_path / "r.json"
    old.write_bytes(OLD)
    with output_folder(tmp_path / "report") as folder, output_file(old, force=True) as tmp:
        (folder / "report.html").write_text("half")
        tmp.write_text("half")
        remove_unfinished()  # the watchdog, mid-write
        assert not folder.exists() and not tmp.exists()
        folder.mkdir()  # the block goes on as a live process would (nothing to rename afterwards)
        tmp.write_text("{}")
    assert old.read_bytes() != OLD  # a process that was not killed finishes as usual
    remove_unfinished()  # nothing registered any more: nothing removed
    assert old.exists()


@pytest.mark.parametrize("forced", [True, False], ids=["forced-exit", "keyboard-interrupt"])
def test_a_ctrl_c_while_the_place_is_probed_leaves_no_probe(tmp_path, monkeypatch, forced):
    """The check before writing tries the folder with a probe file; a Ctrl-C that comes between
    creating and removing it (seen in CI: `.wearbench-probe-<pid>` left in the output folder) removes
    it, whether the watchdog's forced exit takes the process or the interrupt unwinds it."""
    from wearbench.bench.output_file import check_output, remove_unfinished

    touch = Path.touch

    def touch_then_ctrl_c(self, *args, **kwargs):
        touch(self, *args, **kwargs)
        if forced:
            remove_unfinished()  # the watchdog's way out, right after the probe was created
            raise SystemExit(130)
        raise KeyboardInterrupt

    monkeypatch.setattr(Path, "touch", touch_then_ctrl_c)
    with pytest.raises((SystemExit, KeyboardInterrupt)):
        check_output(tmp_path / "r.json")
    assert list(tmp_path.iterdir()) == []


def test_a_forced_exit_while_a_folder_is_moved_into_place_leaves_no_partial_folder(tmp_path, monkeypatch):
    """``--force`` into a folder that exists: the new files are moved in one by one; a forced exit
    between two moves leaves the files moved so far and the old ones, never the temporary folder."""
    from wearbench.bench import output_file as module

    report = tmp_path / "report"
    report.mkdir()
    (report / "a.png").write_bytes(OLD)
    (report / "b.png").write_bytes(OLD)
    check, at_exit = module.check_output, []

    def check_then_forced_exit(path, **kwargs):
        if Path(path).name == "b.png":  # a.png is in place, b.png not yet
            module.remove_unfinished()  # then os._exit: no finally runs, what is on disk now stays
            at_exit.extend(sorted(p.name for p in tmp_path.iterdir()))
            assert (report / "a.png").read_text() == "new" and (report / "b.png").read_bytes() == OLD
            raise SystemExit(130)
        return check(path, **kwargs)

    with pytest.raises(SystemExit), module.output_folder(report, force=True) as folder:
        (folder / "a.png").write_text("new")
        (folder / "b.png").write_text("new")
        monkeypatch.setattr(module, "check_output", check_then_forced_exit)
    assert at_exit == ["report"]
