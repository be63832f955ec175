"""The pytest plugin as a lab meets it: fixtures listed with their docstrings, a fault plan that is
the emulators' own, and nothing left behind (process, pty, temporary folder, lock or ballast file)
when a test fails on purpose or the run is interrupted with Ctrl-C mid-session."""

from __future__ import annotations

import contextlib
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import psutil
import pytest
from wearbench.acquisition.session_file import read_session
from wearbench.hardware.emulators.config import EmulatorConfig
from wearbench.testing import FaultPlan, assert_identifies, assert_no_sample_lost, assert_valid_mcap

FIXTURES = ("wearbench_bench", "serial_bench", "can_bench", "canopen_bench", "record_session", "wearbench_speedup")

MINI = '''
import json, os
from wearbench.testing import open_benches

def _note(bench, tmp_path):
    with open(os.environ["HIL_NOTES"], "a") as fh:
        fh.write(json.dumps({"pid": bench.pid, "port": bench.port, "channel": bench.channel,
                             "tmp": str(tmp_path), "sent_dir": str(bench._tmp) if bench._tmp else None}) + "\\n")

def test_fails_on_purpose(serial_bench, can_bench, record_session, tmp_path):
    serial, can = serial_bench(signal="harmonic"), can_bench(signal="harmonic")
    _note(serial, tmp_path)
    _note(can, tmp_path)
    assert len(open_benches()) == 2
    assert record_session(serial, duration=0.5, speed=6.283).completed
    assert False, "failing on purpose"

def test_interrupted(serial_bench, record_session, tmp_path):
    serial = serial_bench(signal="harmonic")
    _note(serial, tmp_path)
    record_session(serial, duration=120, speed=6.283)
'''


def _run_mini(tmp_path: Path, test: str, *, interrupt_when=None, group: bool = False
              ) -> tuple[subprocess.CompletedProcess, list[dict]]:
    """Run one test of MINI in its own pytest; ``interrupt_when(notes)``: send SIGINT once it is true
    (``group``: to the whole process group, as a terminal's Ctrl-C is, emulators included)."""
    suite = tmp_path / "lab"
    suite.mkdir(exist_ok=True)
    (suite / "pytest.ini").write_text("[pytest]\naddopts = -p no:cacheprovider\n")
    (suite / "test_mini.py").write_text(MINI)
    notes = tmp_path / f"{test}.jsonl"
    env = {**os.environ, "HIL_NOTES": str(notes)}
    cmd = [sys.executable, "-m", "pytest", "-q", str(suite / "test_mini.py"), "-k", test,
           "--basetemp", str(tmp_path / f"base-{test}"), "--wearbench-speedup", "2"]
    proc = subprocess.Popen(cmd, cwd=suite, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            start_new_session=group)
    if interrupt_when is not None:
        deadline = time.monotonic() + 120
        while not interrupt_when(notes) and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.2)
        if group:
            os.killpg(proc.pid, signal.SIGINT)
        else:
            proc.send_signal(signal.SIGINT)
    out, _ = proc.communicate(timeout=120)
    lines = notes.read_text().splitlines() if notes.exists() else []
    return subprocess.CompletedProcess(cmd, proc.returncode, out), [json.loads(x) for x in lines]


def _nothing_left(notes: list[dict]) -> None:
    for note in notes:
        if note["pid"] is not None:
            with pytest.raises(ProcessLookupError):
                os.kill(note["pid"], 0)  # the emulator process has ended
        if note["port"] is not None:
            assert not Path(note["port"]).exists(), f"pty {note['port']} still there"
        if note["sent_dir"] is not None:
            assert not Path(note["sent_dir"]).exists(), f"{note['sent_dir']} still there"
        tmp = Path(note["tmp"])
        left = [p.name for p in tmp.iterdir() if p.suffix in (".lock", ".ballast", ".new") or p.name.startswith(".")]
        assert left == [], f"left in {tmp}: {left}"


def test_pytest_fixtures_lists_the_plugins_fixtures_with_docstrings(tmp_path):
    (tmp_path / "test_nothing.py").write_text("def test_nothing():\n    pass\n")
    r = subprocess.run([sys.executable, "-m", "pytest", "--fixtures", "-p", "no:cacheprovider", str(tmp_path)],
                       cwd=tmp_path, capture_output=True, text=True, timeout=120, check=False)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "fixtures defined from wearbench.testing.plugin" in r.stdout
    for name in FIXTURES:
        assert f"\n{name}" in r.stdout, name
    assert "pseudo-terminal" in r.stdout and "CiA 402" in r.stdout and "virtual" in r.stdout
    h = subprocess.run([sys.executable, "-m", "pytest", "--help"], cwd=tmp_path, capture_output=True, text=True,
                       timeout=120, check=False).stdout
    for option in ("--wearbench-port", "--wearbench-can", "--wearbench-speedup", "--wearbench-bench"):
        assert option in h
    markers = subprocess.run([sys.executable, "-m", "pytest", "--markers"], cwd=tmp_path, capture_output=True,
                             text=True, timeout=120, check=False).stdout
    assert "@pytest.mark.realtime(duration)" in markers


@pytest.mark.slow
def test_a_failing_test_leaves_nothing_behind(tmp_path):
    r, notes = _run_mini(tmp_path, "fails_on_purpose")
    assert r.returncode == 1 and "failing on purpose" in r.stdout, r.stdout
    assert len(notes) == 2 and notes[1]["channel"].startswith("wearbench-hil-")
    _nothing_left(notes)
    session = Path(notes[0]["tmp"]) / "session.mcap"
    assert_valid_mcap(session)
    assert read_session(session).metadata["result"]["reason"] == "completed"


def _recording(notes: Path) -> bool:
    """The interrupted test's session file holds a few chunks."""
    if not notes.exists() or not notes.read_text():
        return False
    session = Path(json.loads(notes.read_text().splitlines()[0])["tmp"]) / "session.mcap"
    return session.exists() and session.stat().st_size > 100_000


@pytest.mark.slow
@pytest.mark.parametrize("group", [False, True], ids=["sigint-to-pytest", "terminal-ctrl-c"])
def test_ctrl_c_mid_session_leaves_a_finished_file_and_nothing_else(tmp_path, group):
    """Also a terminal's Ctrl-C, which reaches the emulator's process too (issue 46): it took it, died,
    and the recorder saw a lost device instead of the Ctrl-C; the run went on and ended with exit 0."""
    r, notes = _run_mini(tmp_path, "interrupted", interrupt_when=_recording, group=group)
    assert r.returncode == 2 and "KeyboardInterrupt" in r.stdout, r.stdout  # pytest: interrupted
    assert len(notes) == 1
    _nothing_left(notes)
    session = Path(notes[0]["tmp"]) / "session.mcap"
    assert_valid_mcap(session)
    s = read_session(session)
    assert s.finished and "interrupted (SIGINT)" in s.metadata["result"]["reason"]
    assert_no_sample_lost(session)  # no gap in what was recorded


def test_the_fault_plan_is_the_emulators_own(wearbench_bench):
    plan = FaultPlan(drop_link_at=1.5, garbage_at="2 s", garbage_bytes=64, stall_device_at=3.0, motor_fault_at=4.0,
                     lose_index_at=2.5, clock_drift="40 ppm", drop_rate=0.01)
    assert not plan.clean and FaultPlan().clean and plan.first_fault() == 1.5
    config = EmulatorConfig.from_table(plan.apply({"signal": "harmonic"}), bench=wearbench_bench)
    f = config.faults
    assert (f.disconnect_after, f.garbage_at, f.garbage_bytes, f.freeze_at, f.stall_at, f.index_lost_at,
            f.drop_rate) == (1.5, 2.0, 64, 3.0, 4.0, 2.5, 0.01)
    assert config.accelerometer.drift == pytest.approx(40e-6)
    assert EmulatorConfig.from_table(FaultPlan(clock_drift=1e-4).apply({}), bench=wearbench_bench
                                     ).accelerometer.drift == pytest.approx(1e-4)


def test_raw_can_garbage_is_counted_and_loses_nothing(can_bench, record_session):
    """Frames of random bytes on the accelerometer's identifier: refused as malformed, every real
    block recorded, /can/frames in log-time order with the host's frames in it."""
    bench = can_bench(signal="harmonic", faults=FaultPlan(garbage_at=1.0, garbage_bytes=80))
    rec = record_session(bench, duration=2.0, speed=2 * math.pi)
    assert rec.completed, rec.reason
    assert rec.result.malformed == 10 and (rec.session.events.kind == "malformed").sum() == 10
    assert_no_sample_lost(rec, bench.sent())
    assert_valid_mcap(rec)


def test_real_hardware_options_point_the_fixtures_at_the_bench(tmp_path):
    """--wearbench-port / --wearbench-can: no emulator starts, the handle names the port or bus,
    and a test with a fault plan skips (faults need the emulator)."""
    (tmp_path / "pytest.ini").write_text("[pytest]\naddopts = -p no:cacheprovider\n")
    (tmp_path / "test_hw.py").write_text(
        "from wearbench.testing import FaultPlan\n"
        "def test_serial(serial_bench):\n"
        "    b = serial_bench()\n"
        "    assert not b.emulated and b.options == {'port': '/dev/ttyBENCH'} and b.pid is None\n"
        "def test_can(can_bench, canopen_bench):\n"
        "    assert can_bench().options == {'interface': 'socketcan', 'channel': 'can0'}\n"
        "    assert canopen_bench().backend == 'canopen'\n"
        "def test_fault(serial_bench):\n"
        "    serial_bench(faults=FaultPlan(drop_link_at=1.0))\n")
    r = subprocess.run([sys.executable, "-m", "pytest", "-rs", str(tmp_path), "--wearbench-port", "/dev/ttyBENCH",
                        "--wearbench-can", "socketcan:can0"], cwd=tmp_path, capture_output=True, text=True,
                       timeout=120, check=False)
    assert r.returncode == 0, r.stdout
    assert "2 passed, 1 skipped" in r.stdout and "fault injection needs the emulator" in r.stdout
    assert "wearbench: serial /dev/ttyBENCH, CAN socketcan:can0" in r.stdout


@pytest.mark.slow
def test_a_non_twin_session_on_the_pty_identifies_as_its_state(serial_bench, record_session, wearbench_bench):
    """The model's physics through the serial emulator (a bench drawn with a seed no ensemble
    uses), recorded, then assert_identifies against small ensembles of two candidates: the true
    state passes, the other fails with a message naming its probability."""
    from wearbench.compute.options import QUIET
    from wearbench.validation.inference.ensemble import EnsembleSettings, build_ensembles

    states = [s for s in wearbench_bench.states if s.name in ("0.3 mm new", "0.6 mm new")]
    ensembles = build_ensembles(wearbench_bench, states, settings=EnsembleSettings(realisations=4, cycles=6),
                                shipped=False, compute=QUIET)
    bench = serial_bench(state="0.6 mm new", seed=7021, table={"signal": "model", "revolutions": 14})
    rec = record_session(bench, cycles=8)
    assert rec.completed, rec.reason
    assert_valid_mcap(rec)
    r = assert_identifies(rec, "0.6 mm new", p_min=0.9, ensembles=ensembles)
    assert r.verdict == "0.6 mm new"
    with pytest.raises(AssertionError, match=r"identifies as '0.3 mm new' with p 0\.\d+ < 0.5"):
        assert_identifies(rec, "0.3 mm new", p_min=0.5, ensembles=ensembles)


# ----------------------------------------------------------------------------------------------
# Issue 46: a terminal Ctrl-C in a lab's suite (examples/hil) let the run finish with exit code 0 or
# failed a test falsely ("device disconnected"): the recorder in the lab's script took the Ctrl-C as
# a clean stop and returned, and the emulator's process took it too and died. Now every moment ends
# the run as interrupted, with nothing left behind.

HIL = Path(__file__).resolve().parents[2] / "examples" / "hil"
HIL_MOMENTS = {  # (base folder, the run's processes' command lines) -> now
    # the first emulator starting: multiprocessing's fork server (its parent) is being started
    "emulator-starting": lambda base, running: any("forkserver" in p for p in running),
    # the lab's script recording: from a serial emulator, one that will drop its link, the CANopen drive
    "lab-script-recording": lambda base, running: _size(base / "test_a_clean_run_is_usable0" / "run.mcap") > 20_000,
    "link-about-to-drop": lambda base, running: _size(base / "test_lost_link0" / "run.mcap") > 0,
    "canopen-drive-recording": lambda base, running: _size(base / "test_motor_fault0" / "run.mcap") > 0,
}


def _size(path: Path) -> int:
    try:
        return path.stat().st_size
    except OSError:
        return -1


@pytest.mark.slow
@pytest.mark.parametrize("moment", list(HIL_MOMENTS))
def test_a_terminal_ctrl_c_in_a_lab_suite_stops_the_run_as_interrupted(moment, tmp_path):
    suite, base = tmp_path / "hil", tmp_path / "base"
    shutil.copytree(HIL, suite)
    # the emulators' temporary folders: here, to be counted; short, as a lab's is: multiprocessing's fork
    # server listens on a socket inside it, and a socket's path holds at most 107 bytes
    tmp = Path(tempfile.mkdtemp(prefix="wb-hil-"))
    env = {**os.environ, "TMPDIR": str(tmp)}
    proc = subprocess.Popen([sys.executable, "-m", "pytest", "--wearbench-speedup", "4", "--basetemp", str(base)],
                            cwd=suite, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            start_new_session=True)
    out: list[str] = []
    reader = threading.Thread(target=lambda: out.extend(proc.stdout), daemon=True)
    reader.start()
    watched, started, sent = psutil.Process(proc.pid), set(), None
    try:
        deadline = time.monotonic() + 240
        while proc.poll() is None and time.monotonic() < deadline:
            running = []
            with contextlib.suppress(psutil.Error):
                children = watched.children(recursive=True)
                started |= {p.pid for p in children}
                running = [" ".join(p.cmdline()) for p in children]
            if HIL_MOMENTS[moment](base, running):
                sent = time.monotonic()
                os.killpg(proc.pid, signal.SIGINT)
                break
            time.sleep(0.02)
        assert sent is not None, f"the run ended (exit {proc.returncode}) before {moment}: {''.join(out)}"
        proc.wait(timeout=120)
        took = time.monotonic() - sent
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    reader.join(timeout=30)
    text = "".join(out)
    assert proc.returncode == 2 and "KeyboardInterrupt" in text, text  # pytest: interrupted
    assert "failed" not in text.splitlines()[-1] and "FAILED" not in text and "ERROR" not in text, text
    assert "device disconnected" not in text, text
    assert took < 30, took  # the interrupted test ends its own way (a recorder finishes its file), no more
    left = started
    for _ in range(50):  # an emulator is killed at once; multiprocessing's fork server ends with pytest,
        # in its own time (its interpreter's exit: up to a second or two on a loaded machine)
        left = [p for p in left if psutil.pid_exists(p) and psutil.Process(p).status() != psutil.STATUS_ZOMBIE]
        if not left:
            break
        time.sleep(0.1)
    assert not left, [" ".join(psutil.Process(p).cmdline()) for p in left]
    assert sorted(p.name for p in tmp.iterdir() if p.name.startswith("wearbench-")) == []
    shutil.rmtree(tmp, ignore_errors=True)
