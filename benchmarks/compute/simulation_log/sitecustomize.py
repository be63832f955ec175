"""What every simulation of a test run costs, and who asked for it: ``suite_durations.py --simulations``
puts this folder on ``PYTHONPATH`` (so every Python process of the run, commands and cluster workers
included, loads it at start-up) and names it a pytest plugin (``PYTEST_PLUGINS``, for pytest and its
workers, whose assertion rewriting imports the package before any other import hook sees it).

With ``$WEARBENCH_SIMULATION_LOG`` set, each call of the model's entry points (``simulate``,
``run_stages``, and the emulator's truth tables ``run_table`` and ``model_table``) appends one JSON line
to that file: the function, how deep it was inside another logged call, the calling module (the
nearest frame outside the model), the test (``$PYTEST_CURRENT_TEST``, inherited by the processes a
test starts) and the call's CPU seconds in its thread. Without it, this module does nothing.

PYTEST_DONT_REWRITE: loaded before pytest, as a plugin it could not be rewritten anyway (no warning).
"""

from __future__ import annotations

import functools
import importlib.abc
import json
import os
import sys
import threading
import time
import traceback

LOG = os.environ.get("WEARBENCH_SIMULATION_LOG")
ENTRY_POINTS = {"wearbench.model.simulation": ("simulate",), "wearbench.model.wear_stages": ("run_stages",),
                "wearbench.hardware.emulators.signal": ("run_table", "model_table")}
_inside = threading.local()  # per thread: how many logged calls it is in


def _caller() -> str:
    """The module of the nearest frame outside the model and this file (a wearbench module, a test or
    a library), its path from the package root."""
    model = os.path.dirname(sys.modules["wearbench.model"].__file__) + os.sep
    for frame in reversed(traceback.extract_stack()[:-2]):
        name = frame.filename
        if not name.startswith(model) and name != __file__:
            return name.split("/site-packages/")[-1] if "/site-packages/" in name else name
    return "?"


def _logged(function, name: str):
    @functools.wraps(function)
    def call(*args, **kwargs):
        cpu, depth = time.thread_time(), getattr(_inside, "depth", 0)
        _inside.depth = depth + 1
        try:
            return function(*args, **kwargs)
        finally:
            _inside.depth = depth
            line = {"function": name, "depth": depth, "caller": _caller(), "cpu": time.thread_time() - cpu,
                    "test": os.environ.get("PYTEST_CURRENT_TEST", "").split(" ")[0]}
            with open(LOG, "a", encoding="utf-8") as fh:
                fh.write(json.dumps(line) + "\n")

    call.logged = True
    return call


def _wrap(module) -> None:
    """Log the entry points of ``module``, and of every loaded wearbench module that imported them by name."""
    for name in ENTRY_POINTS[module.__name__]:
        original = getattr(module, name)
        if getattr(original, "logged", False):
            continue
        logged = _logged(original, name)
        for other in list(sys.modules.values()):
            if getattr(other, "__name__", "").startswith("wearbench") and getattr(other, name, None) is original:
                setattr(other, name, logged)


class _Finder(importlib.abc.MetaPathFinder):
    """Wraps an entry point's module as soon as it has run (the modules that import it by name run after)."""

    def find_spec(self, fullname, path, target=None):
        if fullname not in ENTRY_POINTS:
            return None
        for finder in sys.meta_path:
            spec = None if finder is self else getattr(finder, "find_spec", lambda *a: None)(fullname, path, target)
            if spec is not None:
                run = spec.loader.exec_module

                def exec_module(module, run=run):
                    run(module)
                    _wrap(module)

                spec.loader.exec_module = exec_module
                return spec
        return None


def pytest_configure(config) -> None:
    """In pytest and its workers: the entry points' modules loaded now (by pytest's import hook, which
    comes before the finder) and wrapped."""
    if LOG:
        from wearbench.hardware.emulators import signal
        from wearbench.model import simulation, wear_stages

        for module in (simulation, wear_stages, signal):
            _wrap(module)


if LOG:
    sys.meta_path.insert(0, _Finder())
