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

import pytest
from wearbench.acquisition.session_file import read_session
from wearbench.bench.load import shipped_bench
from wearbench.bench.output_file import check_output, output_file, output_folder
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
