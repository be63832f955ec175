"""Sessions of an emulated bench whose hidden truth is a candidate state on a drawn bench.

A truth is a state of the bench played by the bench emulator on a bench drawn from the bench file's
``[tolerances]`` with its own seed (None: the nominal model, a twin), seen through the emulator's
sensor chain: what the demo records, and what the identification, window and estimate benchmarks
and tests judge the methods on. :func:`prepare_truth` computes (and caches) the truth's signal
table, :func:`record_state` records a session of it through an acquisition backend.
"""

from __future__ import annotations

import math
from pathlib import Path

from wearbench.acquisition.backends import open_rig
from wearbench.acquisition.recorder import Recorder, revolutions_played
from wearbench.acquisition.session import SessionPlan, SessionResult
from wearbench.acquisition.session_writer import SessionWriter
from wearbench.bench.schema import Bench, WearState
from wearbench.hardware.emulators.config import emulator_config
from wearbench.hardware.emulators.device import BenchDevice

__all__ = ["prepare_truth", "record_state", "slug", "truth_revolutions"]


def slug(name: str) -> str:
    """A state's name as a file name: ``0.3 mm new`` -> ``0p3_mm_new``."""
    return name.replace(" ", "_").replace(".", "p")


def truth_revolutions(bench: Bench, cycles: int) -> int:
    """Motor revolutions of the truth's run for a session of ``cycles`` of ``bench`` (:func:`record_state`).

    The device plays its run, then wraps (replays it, crossfaded), so the run covers what the recorder
    plays of a session (:func:`~wearbench.acquisition.recorder.revolutions_played`: the start-up, the
    cycles and the end) and one crank turn to spare. What a session records is the start of the run,
    the same whatever the run's length; a motor slower to reach its speed plays into the wrap.
    """
    played = revolutions_played(bench, SessionPlan(speed=bench.speed, cycles=cycles))
    return math.ceil(played + 1 / abs(bench.encoder_driver.ratio))


def prepare_truth(bench: Bench, state: WearState, seed: int | None, **emulator) -> str:
    """Compute the emulator's signal table for a truth (cached on disk, so recording starts at once)."""
    return BenchDevice(bench, emulator_config(bench, state, seed, **emulator)).prepare(bench.speed).source


def record_state(bench: Bench, state: WearState, seed: int | None, out: Path, *, backend: str, cycles: int,
                 on_progress=None, recorders: list | None = None, **emulator) -> SessionResult:
    """Record one session of the emulated ``bench`` whose hidden truth is ``state`` drawn with ``seed``
    (None: the nominal model, a twin) through the ``backend`` driver (``serial``: the emulator on a
    pseudo-terminal in its own process, in real time; ``sim``: in-process, as fast as the host can)
    to ``out``, which it replaces when the session finishes; the SessionResult.
    ``emulator``: top-level ``[emulator]`` keys (e.g. ``revolutions``) for ``emulator_config``;
    ``recorders``: the Recorder is appended to it before it runs (so another thread can stop it).
    Raises RuntimeError when the session stops early (the file holds what was recorded until then)."""
    table = emulator_config(bench, state, seed, **emulator).to_table()
    plan = SessionPlan(speed=bench.speed, cycles=cycles, operator="wearbench demo",
                       clearances=dict(state.clearances),
                       wear={j: str(p) for j, p in state.surfaces.items()})  # the files: attached
    proc = None
    if backend == "serial":
        from wearbench.hardware.emulators.serial_server import start_serial_emulator

        proc, port = start_serial_emulator(bench, table)
        options: dict = {"port": port}
    else:
        options = {"speedup": math.inf, "config": table}
    try:
        rig = open_rig(bench.with_clearances(plan.clearances), backend, options)
        try:
            recorder = Recorder(rig, bench, plan, out, on_progress=on_progress,
                                writer=SessionWriter(out, replace=True))
            if recorders is not None:
                recorders.append(recorder)
            result = recorder.run()
        finally:
            rig.close()
    finally:
        if proc is not None:
            proc.terminate()
            proc.wait(timeout=30)
    if not result.completed:
        raise RuntimeError(f"session {out} stopped early: {result.reason} (the file holds what was "
                           "recorded until then)")
    return result
