"""Ctrl-C: every command ends within about a second, with one line on stderr and exit code 130.

Real processes get a real SIGINT (recording commands are covered in tests/acquisition/test_failures.py:
their file is finished)."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from wearbench.cli.progress import COMPILING

STOP_WITHIN = 3.0  # s: generous bound for a loaded machine; the watchdog ends a command after 0.5 s


def _interrupt(args: list[str], after: float, env: dict | None = None) -> tuple[int, str, float]:
    """Start ``wearbench ARGS``, send SIGINT ``after`` seconds, return (exit code, stderr, seconds to stop)."""
    proc = subprocess.Popen([sys.executable, "-m", "wearbench.cli", *args], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, env=env)
    time.sleep(after)
    sent = time.monotonic()
    proc.send_signal(signal.SIGINT)
    try:
        _, err = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        proc.kill()
        raise AssertionError("still running 60 s after Ctrl-C") from None
    return proc.returncode, err, time.monotonic() - sent


def _said(err: str) -> list[str]:
    """stderr less what a command says on its way: the cold-cache note and progress lines (off a
    terminal progress is lines ending in the elapsed time, e.g. ``theory ensembles: 7/64 ... (3 s)``)."""
    return [x for x in err.splitlines() if not x.startswith("compiling") and not re.search(r"\(\d+ s\)$", x)]


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


def test_a_cold_start_says_it_compiles_and_stops_while_compiling(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba")}  # nothing compiled yet
    code, err, took = _interrupt(["simulate", "slider-crank"], after=4.0, env=env)
    assert err.splitlines()[0] == COMPILING
    _assert_one_line(code, err, took, "simulate")


def _interrupt_group(args: list[str], after: float, cwd) -> tuple[int, str]:
    """Ctrl-C as a terminal sends it: SIGINT to the whole process group (workers included)."""
    proc = subprocess.Popen([sys.executable, "-m", "wearbench.cli", *args], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, start_new_session=True, cwd=cwd)
    time.sleep(after)
    os.killpg(proc.pid, signal.SIGINT)
    try:
        _, err = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        raise AssertionError("still running 60 s after Ctrl-C") from None
    time.sleep(1.0)  # the resource tracker speaks (if at all) once the last process is gone
    return proc.returncode, err


@pytest.mark.slow
@pytest.mark.parametrize("args", [
    ["sweep", "slider-crank", "--vary", "clearance=0.1mm..0.5mm:40", "--workers", "2", "--out"],
    ["ensemble", "ninebar-testbed", "--realisations", "16", "--workers", "2", "--out"],
])
def test_ctrl_c_on_a_local_cluster_leaves_no_worker_traceback_or_leaked_semaphores(args, tmp_path):
    """Issue 25, item 11: Ctrl-C during identify, ensemble or sweep printed Dask worker tracebacks
    (3 of 17 tries) and a leaked-semaphore warning (16 of 17)."""
    for after in (8.0, 14.0):  # each try its own output (a try the signal missed finishes and writes it)
        out = f"out{after:g}" + (".npz" if args[0] == "ensemble" else "")
        code, err = _interrupt_group([*args, out], after, tmp_path)
        if code == 0:
            continue
        assert code == 130 and _said(err) == [f"wearbench {args[0]}: interrupted"], err


def test_a_ctrl_c_before_the_command_is_parsed_still_names_it(monkeypatch, capsys):
    """A slow start (imports on a loaded machine) can take the Ctrl-C before the parser has run: the
    line still names the command the user typed."""
    from wearbench import cli

    def interrupted():
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "build_parser", interrupted)
    assert cli.main(["compare", "session.mcap"]) == 130
    assert capsys.readouterr().err.strip() == "wearbench compare: interrupted"
    assert cli.main(["--help"]) == 130  # no command typed: the program's name
    assert capsys.readouterr().err.strip() == "wearbench: interrupted"
