"""What a batch of simulations will cost, said before it starts.

A batch's CPU time is the motor revolutions its tasks simulate (``Task.revolutions``) times what one
revolution of the bench costs on this machine. That price is measured once by a pilot, one realisation
of the bench in the batch's state at its speed and output rate (a short warm-up, so loading the compiled
kernels is not counted, then 1.5 revolutions timed on the process's CPU clock), and kept per bench
physics, state, speed, output rate, model source and machine in ``$WEARBENCH_CACHE/costs``: seconds
on the first batch of a bench, nothing after. Tasks the result cache already holds cost nothing.

:func:`estimate` prices a batch (a :class:`Cost` says what its revolutions simulate), :func:`describe`
says it in one line; ``Compute.run`` prints that line before the batch starts, and a builder of several
batches (an estimator: wear runs, then ensembles) prints its whole plan first with
``Compute.announce``. Imports the bench, the model's realisations and the task cache.
"""

from __future__ import annotations

import json
import os
import platform
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

from wearbench.bench.content import bench_key, cache_folder, canonical
from wearbench.bench.schema import Bench, WearState
from wearbench.compute.task_cache import cached, task_key
from wearbench.model.digest import model_source_digest

__all__ = ["Cost", "Priced", "describe", "estimate", "plan_line", "revolution_seconds", "workers_of"]

PILOT = 1.5  # motor revolutions the pilot times (after a settling half revolution)


@dataclass(frozen=True)
class Cost:
    """What a batch's revolutions simulate: ``bench`` in ``state`` at commanded motor ``speed`` (rad/s)
    on an output grid of ``output_rate`` Hz; ``noun`` names its tasks ("realisations", "wear runs")."""

    bench: Bench
    state: WearState
    speed: float
    output_rate: float = 20_000.0
    noun: str = "simulations"


@dataclass(frozen=True)
class Priced:
    """A batch priced: ``tasks`` in all, ``cached`` of them served by the result cache, the CPU seconds
    of the rest (None: not priced) at ``per_revolution`` s each, on ``workers`` (None: unknown)."""

    label: str
    noun: str
    tasks: int
    cached: int = 0
    cpu: float | None = None
    per_revolution: float | None = None
    workers: int | None = None
    notes: tuple[str, ...] = field(default_factory=tuple)

    @property
    def wall(self) -> float | None:
        """About how long it takes (s) on its workers (None when either is unknown)."""
        if self.cpu is None or not self.workers:
            return None
        return self.cpu / max(1, min(self.workers, self.tasks - self.cached))


def _pilot_key(cost: Cost) -> str:
    """The price's key: a model source with the same outputs (``model/equivalence.toml``) may run at
    another speed, so the source itself, not only its results, is part of it."""
    return task_key("revolution-cost", bench_key(cost.bench), canonical(cost.state), round(float(cost.speed), 9),
                    float(cost.output_rate), model_source_digest(), platform.node(), platform.machine(),
                    os.cpu_count())


def revolution_seconds(cost: Cost) -> float:
    """CPU seconds one motor revolution of ``cost``'s bench, state and speed takes on this machine:
    measured by a pilot the first time (see the module docstring), then read from the cache."""
    from wearbench.model.realisation import simulate_state

    path = cache_folder("costs") / f"{_pilot_key(cost)}.json"
    try:
        return float(json.loads(path.read_text())["seconds_per_revolution"])
    except (OSError, ValueError, KeyError):
        pass
    simulate_state(cost.bench, cost.state, 1, revolutions=0.05, settle=0.0, speed=cost.speed,
                   output_rate=cost.output_rate)  # compiled kernels loaded (or compiled) outside the clock
    start = time.process_time()
    simulate_state(cost.bench, cost.state, 1, revolutions=PILOT, settle=0.5, speed=cost.speed,
                   output_rate=cost.output_rate)
    seconds = max(time.process_time() - start, 1e-6) / (PILOT + 0.5)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps({"seconds_per_revolution": seconds, "bench": cost.bench.name,
                                    "state": cost.state.name, "speed": cost.speed, "output_rate": cost.output_rate,
                                    "measured": time.strftime("%Y-%m-%dT%H:%M:%S")}))
    except OSError:  # a read-only cache: measured again next time
        pass
    return seconds


def estimate(tasks: Sequence, label: str, cost: Cost | None, *, workers: int | None = None,
             cache: bool = True) -> Priced:
    """The batch ``tasks`` (``compute.Task``) priced: how many the result cache holds (with ``cache``),
    and the CPU seconds of the rest from their ``revolutions`` at :func:`revolution_seconds` of
    ``cost`` (none without a cost, or when nothing is left to run)."""
    todo = [t for t in tasks if not (cache and cached(t.key))]
    noun = cost.noun if cost is not None else "simulations"
    if cost is None or not todo:
        return Priced(label, noun, len(tasks), len(tasks) - len(todo), 0.0 if not todo else None, workers=workers)
    per = revolution_seconds(cost)
    revolutions = sum(float(getattr(t, "revolutions", 0.0)) for t in todo)
    return Priced(label, noun, len(tasks), len(tasks) - len(todo), per * revolutions, per, workers)


def _duration(seconds: float) -> str:
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def describe(priced: Priced) -> str:
    """The batch in one line: what it builds, how much of it is cached, its CPU time and, on known
    workers, about how long it takes."""
    p = priced
    done = f" ({p.cached} cached)" if p.cached else ""
    text = f"{p.label}: {p.tasks} {p.noun}{done}"
    if p.cached == p.tasks:
        return text + ": all cached, no simulation"
    if p.cpu is None:
        return text + "; CPU time not estimated"
    text += f", about {_duration(p.cpu)} of CPU"
    if p.per_revolution is not None:
        text += f" ({p.per_revolution:.3g} s per motor revolution, measured on this machine)"
    if p.wall is not None and p.workers and p.workers > 1:
        text += f", about {_duration(p.wall)} on {p.workers} workers"
    return text + "".join(f"; {n}" for n in p.notes)


def plan_line(label: str, parts: Sequence[tuple[str, int, float]], cost: Cost, *, workers: int | None = None) -> str:
    """One line for a builder of several batches before any starts: ``parts`` (noun, count, revolutions
    of each) priced at ``cost``'s revolution, cache not consulted (the later batches' tasks are not
    known yet)."""
    per = revolution_seconds(cost)
    cpu = per * sum(count * revs for _, count, revs in parts)
    what = " and ".join(f"{count} {noun}" for noun, count, _ in parts)
    text = f"{label}: {what}, about {_duration(cpu)} of CPU ({per:.3g} s per motor revolution, measured on this machine"
    text += "; less what the result cache holds)"
    if workers and workers > 1:
        text += f", about {_duration(cpu / workers)} on {workers} workers"
    return text


def workers_of(workers: int | None, scheduler: str | None) -> int | None:
    """The workers a batch runs on: ``workers`` (0: this process, 1), the usable cores for a local
    cluster, None for a running cluster (unknown here)."""
    from wearbench.compute.cluster import usable_cores

    if workers == 0:
        return 1
    if workers is not None:
        return workers
    if scheduler not in (None, "local"):
        return None
    return usable_cores()

