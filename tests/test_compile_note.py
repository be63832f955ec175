"""The first run of a model version says that its kernels are compiling (minutes of silence
otherwise), whichever command compiles them: one listener on numba's compile event while
``wearbench.cli.main`` runs a command (issue 46, item 6: the first ``record`` after install was
silent for over 3 minutes)."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
import time

import numba
import psutil
import pytest
from numba.core import event
from wearbench.cli.progress import COMPILING, compile_note


def _function(module: str, name: str):
    """A fresh Python function that says it lives in ``module`` (as numba's event names it)."""
    space: dict = {"__name__": module}
    exec(f"def {name}(x):\n    return 2.0 * x + 1.0\n", space)  # noqa: S102 - a test's own source
    return space[name]


@pytest.mark.no_kernels  # toy functions only
def test_the_note_comes_once_when_a_wearbench_kernel_compiles_never_for_others(capsys):
    with event.install_listener("numba:compile", compile_note()):
        assert numba.njit(_function("labcode.analysis", "other"))(1.0) == 3.0
        assert capsys.readouterr().err == ""  # not ours: not our note
        assert numba.njit(_function("wearbench.model.kernel_test", "first"))(1.0) == 3.0
        assert numba.njit(_function("wearbench.model.kernel_test", "second"))(1.0) == 3.0
    assert capsys.readouterr().err == COMPILING + "\n"


def test_kernels_loaded_from_a_warm_cache_say_nothing():
    """The model's kernels as a command loads them (the warm-up every local cluster worker runs):
    from the on-disk cache nothing compiles, so nothing is said."""
    code = ("from wearbench.cli.progress import compile_note_on\nfrom wearbench.compute.cluster import warm_up\n"
            "with compile_note_on():\n    warm_up()\n    warm_up()\n")
    subprocess.run([sys.executable, "-c", code], check=True, timeout=600)  # compiled, if it was not
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=False)
    assert r.returncode == 0 and r.stderr == "", r.stderr


def _cold_start(args: list[str], tmp_path, *, when_said=None) -> tuple[int, list[str], list[str]]:
    """Run ``wearbench ARGS`` with empty caches (numba's and wearbench's: the emulator's tables too),
    wait for the compile note, then Ctrl-C (SIGINT to its process group: it compiles for a minute
    or two). Returns (exit code, stderr lines, command lines of its child processes when it said it)."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba"), "WEARBENCH_CACHE": str(tmp_path / "cache")}
    proc = subprocess.Popen([sys.executable, "-m", "wearbench.cli", *args], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, env=env, cwd=tmp_path, start_new_session=True)
    lines: list[str] = []
    said = threading.Event()

    def read() -> None:
        for line in proc.stderr:
            lines.append(line.rstrip("\n"))
            if line.startswith("compiling"):
                said.set()

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    children: list[str] = []
    try:
        assert said.wait(240), f"no compile note: {lines}"
        children = [" ".join(p.cmdline()) for p in psutil.Process(proc.pid).children(recursive=True)]
        time.sleep(1.0)  # compiling now
        os.killpg(proc.pid, signal.SIGINT)
        proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    reader.join(timeout=30)
    return proc.returncode, lines, children


def _said(lines: list[str]) -> list[str]:
    """stderr less progress lines (off a terminal: lines ending in the elapsed time, ``(3 s)``)."""
    return [x for x in lines if not re.search(r"\(\d+ s\)$", x)]


@pytest.mark.own_kernels
def test_record_on_the_sim_backend_says_it_compiles(tmp_path):
    """The sim backend's emulator simulates the model: the first `record` compiled silently."""
    code, lines, _ = _cold_start(["record", "ninebar-testbed", "--backend", "sim", "--duration", "0.3s",
                                  "--out", str(tmp_path / "s.mcap")], tmp_path)
    assert _said(lines) == [COMPILING, "wearbench record: interrupted"] and code == 130, lines
    assert not (tmp_path / "s.mcap").exists()  # stopped before its session began


@pytest.mark.own_kernels
def test_emulate_says_it_compiles(tmp_path):
    code, lines, _ = _cold_start(["emulate", "ninebar-testbed", "--serial"], tmp_path)
    assert _said(lines) == [COMPILING, "wearbench emulate: interrupted"] and code == 130, lines


@pytest.mark.own_kernels
def test_a_local_cluster_compiles_once_here_and_says_so(tmp_path):
    """On a cold cache each worker compiled the kernels in its warm-up, all at once and unheard (the
    command's note listens in its own process): the command compiles them first, saying so, and the
    workers load them."""
    code, lines, children = _cold_start(["ensemble", "ninebar-testbed", "--realisations", "4", "--cycles", "2",
                                         "--workers", "2", "--out", str(tmp_path / "e.npz")], tmp_path)
    assert _said(lines) == [COMPILING, "wearbench ensemble: interrupted"] and code == 130, lines
    assert not [c for c in children if "spawn_main" in c], children  # no worker started yet
