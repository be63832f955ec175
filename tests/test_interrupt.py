"""Ctrl-C: every command ends within about a second, with one line on stderr and exit code 130.

Real processes get a real SIGINT (recording commands are covered in tests/acquisition/test_failures.py:
their file is finished)."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import psutil
import pytest
from wearbench.cli.progress import COMPILING

STOP_WITHIN = 3.0  # s: generous bound for a loaded machine; the watchdog ends a command after 0.5 s


def _interrupt(args: list[str], after: float, env: dict | None = None, *, once: str | None = None
               ) -> tuple[int, str, float]:
    """Start ``wearbench ARGS``, send SIGINT ``after`` seconds (with ``once``: that long after the line
    ``once`` appears on stderr, a loaded machine's start-up being no fixed time), return (exit code,
    stderr, seconds to stop)."""
    proc = subprocess.Popen([sys.executable, "-m", "wearbench.cli", *args], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, env=env)
    first = ""
    if once is not None:
        first = proc.stderr.readline()  # blocks until the command says its first line (or ends)
        assert first.rstrip("\n") == once, first
    time.sleep(after)
    sent = time.monotonic()
    proc.send_signal(signal.SIGINT)
    try:
        _, err = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        proc.kill()
        raise AssertionError("still running 60 s after Ctrl-C") from None
    return proc.returncode, first + err, time.monotonic() - sent


def _said(err: str) -> list[str]:
    """stderr less what a command says on its way: the cold-cache note, what it will build and its cost
    (``compute.cost``: ``theory ensembles: 64 realisations, about 3 min of CPU ...``) and progress lines
    (off a terminal progress is lines ending in the elapsed time, e.g. ``theory ensembles: 7/64 ... (3 s)``)."""
    on_the_way = r"\(\d+ s\)$|of CPU|CPU time not estimated|all cached, no simulation"
    return [x for x in err.splitlines() if not x.startswith("compiling") and not re.search(on_the_way, x)]


def _assert_one_line(code: int, err: str, took: float, command: str) -> None:
    assert code == 130, err
    assert "Traceback" not in err and "Error" not in err, err
    assert _said(err) == [f"wearbench {command}: interrupted"], err
    assert took < STOP_WITHIN, took


def test_simulate_stops_at_once():
    # 2000 revolutions take minutes; the compiled loop used to hold Ctrl-C until it was done
    code, err, took = _interrupt(["simulate", "ninebar-testbed", "--clearance", "A=0.6mm,B=0.6mm",
                                  "--revolutions", "2000"], after=6.0)
    _assert_one_line(code, err, took, "simulate")


def test_compare_stops_at_once_wherever_it_is(tmp_path):
    # a Ctrl-C landing in a numba dispatcher used to print a 38-line SystemError traceback
    session = Path(__file__).parent / "acquisition" / "data" / "session_layout1.mcap"  # 2 cycles
    for after in (2.0, 4.0):
        code, err, took = _interrupt(["compare", str(session), "--cycles", "1", "--out", str(tmp_path / f"r{after}")],
                                     after)
        if code == 0:  # finished before the signal: nothing to check
            continue
        _assert_one_line(code, err, took, "compare")


@pytest.mark.own_kernels
def test_a_cold_start_says_it_compiles_and_stops_while_compiling(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba")}  # nothing compiled yet
    code, err, took = _interrupt(["simulate", "slider-crank"], after=1.0, env=env, once=COMPILING)
    assert err.splitlines()[0] == COMPILING
    _assert_one_line(code, err, took, "simulate")


# Where a batch on a local cluster is, from its progress lines (off a terminal: "NAME: 8/40  done 8
# failed 0  remaining 32  (4 s)", the first "NAME: started  done 0 ...").
_PROGRESS = re.compile(r"  done (\d+)  failed \d+  remaining (\d+)  \(\d+ s\)$")
BATCH_MOMENTS: dict[str, Callable[[int, int], bool]] = {  # (done, remaining) -> the moment has come
    "started": lambda done, left: left > 0,  # the workers on their first tasks
    "first-results-in": lambda done, left: done > 0 and left > 0,
    "half-done": lambda done, left: 0 < left <= done,
}


def _interrupt_group(args: list[str], moment: str, cwd) -> tuple[int, str]:
    """Ctrl-C as a terminal sends it (SIGINT to the whole process group, workers included) when the
    command's progress line says the batch has come to ``moment``; returns (exit code, stderr)."""
    proc = subprocess.Popen([sys.executable, "-m", "wearbench.cli", *args], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, start_new_session=True, cwd=cwd)
    said = []
    for line in proc.stderr:  # line by line as the command writes them
        said.append(line)
        if (m := _PROGRESS.search(line.rstrip("\n"))) and BATCH_MOMENTS[moment](int(m[1]), int(m[2])):
            os.killpg(proc.pid, signal.SIGINT)
            break
    else:
        proc.wait()
        raise AssertionError(f"the command ended (exit {proc.returncode}) before {moment}: {''.join(said)}")
    try:
        _, err = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        raise AssertionError("still running 60 s after Ctrl-C") from None
    time.sleep(1.0)  # the resource tracker speaks (if at all) once the last process is gone
    return proc.returncode, "".join(said) + err


@pytest.mark.slow
@pytest.mark.parametrize(("args", "moments"), [
    (["sweep", "slider-crank", "--vary", "clearance=0.1mm..0.5mm:40", "--workers", "2", "--out"],
     ("first-results-in", "half-done")),
    (["ensemble", "ninebar-testbed", "--realisations", "4", "--cycles", "4", "--workers", "2", "--out"],
     ("started", "first-results-in")),
])
def test_ctrl_c_on_a_local_cluster_leaves_no_worker_traceback_or_leaked_semaphores(args, moments, tmp_path):
    """Issue 25, item 11: Ctrl-C during identify, ensemble or sweep printed Dask worker tracebacks
    (3 of 17 tries) and a leaked-semaphore warning (16 of 17). Each try's Ctrl-C comes at a moment of
    the batch named by its progress (the 40-run sweep took 7 s on the 2-core machine, less than the
    fixed 8 s the first Ctrl-C used to wait, and a try that finished was skipped)."""
    for moment in moments:
        out = moment + (".npz" if args[0] == "ensemble" else "")
        code, err = _interrupt_group([*args, out], moment, tmp_path)
        assert code == 130 and _said(err) == [f"wearbench {args[0]}: interrupted"], err


def test_a_ctrl_c_before_the_command_is_parsed_still_names_it(monkeypatch, capsys):
    """A slow start (imports on a loaded machine) can take the Ctrl-C before the parser has run: the
    line still names the command the user typed."""
    from wearbench import cli

    def interrupted(command=None):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "build_parser", interrupted)
    assert cli.main(["compare", "session.mcap"]) == 130
    assert capsys.readouterr().err.strip() == "wearbench compare: interrupted"
    assert cli.main(["--help"]) == 130  # no command typed: the program's name
    assert capsys.readouterr().err.strip() == "wearbench: interrupted"


# A command (registered for the test) whose Ctrl-C a library turns into an error of its own, the
# KeyboardInterrupt dropped: pybind11 did so in matplotlib's savefig ("TypeError: affine_transform():
# incompatible function arguments"), once in CI, at the interrupt test's writing-the-report moment.
SWALLOWED = r'''
import os, signal, sys, time, types
from wearbench import cli

def run(args):
    dropped = False
    try:
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(5)
    except KeyboardInterrupt:  # dropped, as pybind11 clears it: the error below has no context
        dropped = True
    if dropped:
        raise TypeError("incompatible function arguments")

fake = types.ModuleType("wearbench.cli.fake")
fake.register = lambda sub: sub.add_parser("fake").set_defaults(func=run)
sys.modules["wearbench.cli.fake"] = fake
cli.COMMANDS["fake"] = "fake"
sys.argv = ["wearbench", "fake"]
sys.exit(cli.main())
'''


def test_an_error_that_a_library_made_of_a_ctrl_c_still_ends_as_interrupted():
    r = subprocess.run([sys.executable, "-c", SWALLOWED], capture_output=True, text=True, timeout=60, check=False)
    assert (r.returncode, r.stderr.strip()) == (130, "wearbench fake: interrupted"), r.stderr


# ----------------------------------------------------------------------------------------------
# Issue 46, item 4: Ctrl-C was lost in 6 of 14 tries while `identify` started its local cluster
# (SIGINT was ignored in the whole program while the cluster spawned its workers, so that they
# would not take it); the build went on. Now a Ctrl-C at any moment ends the command at once.

IDENTIFY_WITHIN = 5.0  # s: the requirement (the command's own watchdog ends it 0.5 s after the Ctrl-C)
ONE_STATE = '[[state]]\nname = "0.3 mm"\nclearances = { A = "0.3 mm", B = "0.3 mm" }\n'  # not shipped: built


@dataclass
class _Seen:
    """What a watcher sees of a running `wearbench identify`, polled every few ms."""

    t: float = 0.0  # s since the start
    err: str = ""  # stderr so far
    listening: bool = False  # a TCP socket listening: the local scheduler is up
    workers: int = 0  # worker processes running now
    most: int = 0  # the most worker processes seen at once
    first_worker: float | None = None  # t when the first one appeared
    both: float | None = None  # t when both (--workers 2) ran
    partial: bool = False  # the report's temporary folder is there: the report is being written


MOMENTS: dict[str, Callable[[_Seen], bool]] = {  # the 10 moments, in the order a run passes them
    "importing": lambda s: s.t > 0.3,
    "ensembles-to-build": lambda s: "theory ensembles: started" in s.err,  # no cluster yet
    "scheduler-up": lambda s: s.listening,
    "first-worker-spawned": lambda s: s.workers >= 1,
    "workers-importing": lambda s: s.first_worker is not None and s.t > s.first_worker + 0.7,
    "workers-warming-up": lambda s: s.both is not None and s.t > s.both + 2.0,
    "building": lambda s: "1/4" in s.err,
    "last-result-in": lambda s: "4/4" in s.err,  # the cluster closes now
    "cluster-closing": lambda s: "4/4" in s.err and s.workers < s.most,
    "writing-the-report": lambda s: s.partial,
}


def _workers(proc: psutil.Process) -> list[psutil.Process]:
    """The command's child processes that are workers (not multiprocessing's resource tracker)."""
    try:
        return [c for c in proc.children(recursive=True) if "resource_tracker" not in " ".join(c.cmdline())]
    except psutil.Error:
        return []


def _listening(proc: psutil.Process) -> bool:
    try:
        return any(c.status == psutil.CONN_LISTEN for c in proc.net_connections("tcp"))
    except psutil.Error:
        return False


def _identify_interrupted_at(moment: str, folder: Path) -> tuple[int, str, float, set[int], Path]:
    """Run the build in ``folder`` and send a terminal's Ctrl-C when ``moment`` comes. Returns the exit
    code, stderr, seconds from the Ctrl-C to the exit, the worker pids seen and the output folder."""
    folder.mkdir()
    (folder / "states.toml").write_text(ONE_STATE)
    out = folder / "out"
    out.mkdir()
    env = {**os.environ, "WEARBENCH_CACHE": str(folder / "cache")}  # nothing built yet
    session = Path(__file__).parent / "acquisition" / "data" / "session_layout1.mcap"
    args = ["identify", str(session), "--candidates", str(folder / "states.toml"), "--realisations", "4",
            "--ensemble-cycles", "6", "--workers", "2", "--out", str(out / "report"), "--json", str(out / "r.json")]
    proc = subprocess.Popen([sys.executable, "-m", "wearbench.cli", *args], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, env=env, cwd=folder, start_new_session=True)
    err: list[str] = []
    reader = threading.Thread(target=lambda: err.extend(proc.stderr), daemon=True)
    reader.start()
    watched, seen, spawned = psutil.Process(proc.pid), _Seen(), set()
    start, sent = time.monotonic(), None
    try:
        while proc.poll() is None and time.monotonic() - start < 300:
            workers = _workers(watched)
            spawned |= {w.pid for w in workers}
            seen.t, seen.err, seen.workers = time.monotonic() - start, "".join(err), len(workers)
            seen.listening = seen.listening or _listening(watched)
            seen.most = max(seen.most, len(workers))
            seen.first_worker = seen.first_worker if seen.first_worker is not None or not workers else seen.t
            seen.both = seen.both if seen.both is not None or len(workers) < 2 else seen.t
            seen.partial = any(".partial-" in p.name for p in out.iterdir())
            if MOMENTS[moment](seen):
                sent = time.monotonic()
                os.killpg(proc.pid, signal.SIGINT)
                break
            time.sleep(0.01)
        assert sent is not None, f"the command ended (exit {proc.returncode}) before {moment}: {''.join(err)}"
        try:
            proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            raise AssertionError(f"still running 60 s after Ctrl-C at {moment}") from None
        took = time.monotonic() - sent
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    reader.join(timeout=30)  # stderr ends when the last process holding it (the resource tracker) is gone
    return proc.returncode, "".join(err), took, spawned, out


def _finished_whole(code: int, out: Path) -> bool:
    """The command had finished when the Ctrl-C landed (the moment was its last instant): exit 0, the
    report and the JSON written whole, nothing half-written beside them."""
    names = sorted(p.name for p in out.iterdir())
    return code == 0 and names == ["r.json", "report"] and (out / "report" / "report.html").is_file()


@pytest.mark.slow
@pytest.mark.parametrize("moment", list(MOMENTS))
def test_ctrl_c_at_any_moment_of_identify_building_ensembles(moment, tmp_path):
    """A terminal's Ctrl-C (SIGINT to the process group) when the moment comes: exit 130 within 5 s,
    the one line, no process left, nothing half-written in the output folder. A Ctrl-C sent as the
    command writes its last file can land after it finished, whole (on a loaded machine, once in a few
    runs): that try is run again, up to three times; a Ctrl-C must have been heard at the moment."""
    for attempt in range(3):
        code, said, took, spawned, out = _identify_interrupted_at(moment, tmp_path / f"try{attempt}")
        if not _finished_whole(code, out):
            break
    assert code == 130, said
    assert _said(said) == ["wearbench identify: interrupted"], said
    assert took < IDENTIFY_WITHIN, took
    left = [p for p in spawned if psutil.pid_exists(p) and psutil.Process(p).status() != psutil.STATUS_ZOMBIE]
    assert not left, f"worker processes left after Ctrl-C at {moment}: {left}"
    written = sorted(p.name for p in out.iterdir())
    assert not [n for n in written if ".partial-" in n or n == "report"], written  # no report, no half of one
    if written:  # the JSON results, finished before the report: whole
        assert written == ["r.json"] and json.loads((out / "r.json").read_text()), written
