"""Theory as an ensemble: many realisations of each candidate state, reduced to cycle statistics.

Each realisation is one bench drawn within the bench's ``[tolerances]`` with a random start
(``wearbench.model.realisation``), settled, then simulated for ``cycles`` crank revolutions. A
realisation is seen through a sensor path drawn from its seed (``EnsembleSettings.sensor_paths``,
``sensor_path.PathSpread``: a mount/carriage mode and a sensitivity no bench file states), then
reduced on the worker to what the comparison needs (per-cycle features, the filtered curve of each
cycle on a crank-angle grid, per-cycle peaks), so only kilobytes travel back. This is the one place
where a realisation's acceleration becomes features: identification and the estimator's design
both come through it. Realisations run on the compute layer (``wearbench.compute``: dask.distributed,
local by default) and are cached by content: bench physics, state (surfaces by their bytes),
tolerances, seed, settings and the model's source digest.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from wearbench.bench.content import bench_key, file_digest
from wearbench.bench.schema import Bench, WearState
from wearbench.compute.options import DEFAULT, Compute
from wearbench.validation.inference import artefacts
from wearbench.validation.inference.sensor_path import PathSpread
from wearbench.validation.measurement.features import FeatureSpec, cycle_curves, cycle_features
from wearbench.validation.measurement.filters import parse_filter
from wearbench.validation.measurement.scaling import resolve_analysis

__all__ = ["MIN_REALISATIONS", "Ensemble", "EnsembleSettings", "EnsembleSize", "build_ensembles", "check_ensembles_fit",
           "ensembles_key", "load_ensembles", "realisation_keys", "realisation_revolutions", "realisation_summary", "resolve_settings", "save_ensembles",
           "sensor_paths_text"]

@dataclass(frozen=True)
class EnsembleSettings:
    """How many realisations, how long each, and what is kept of them."""

    realisations: int = 64    # M, realisations per state
    cycles: int = 8           # C, settled crank cycles kept per realisation
    settle: float = 2.0       # motor revolutions simulated and dropped first
    seed: int = 1             # realisation i of a state uses seed + i
    output_rate: float = 20_000.0  # Hz, the model's output grid: above the sensor's band so impacts do not alias
    grid: int = 720           # points per revolution of the kept filtered curves
    curve_filter: str = "cfc180"  # filter of the kept curves (bands and window scores)
    features: FeatureSpec = field(default_factory=FeatureSpec)
    # each realisation seen through its own drawn mount (None: the model's acceleration as it is)
    sensor_paths: PathSpread | None = field(default_factory=PathSpread)

    def __post_init__(self) -> None:
        if self.realisations < 3 or self.cycles < 2:
            raise ValueError(f"ensemble: realisations = {self.realisations}, cycles = {self.cycles}: expected at "
                             "least 3 realisations of at least 2 cycles")
        if not self.settle >= 0 or not self.output_rate > 0:
            raise ValueError(f"ensemble: settle = {self.settle}, output_rate = {self.output_rate}: expected "
                             "settle >= 0 revolutions and a positive output rate (Hz)")
        parse_filter(self.curve_filter)
        if self.sensor_paths is not None and not self.sensor_paths.mode[1] < 0.45 * self.output_rate:
            raise ValueError(f"ensemble: sensor paths up to {self.sensor_paths.mode[1]:g} Hz need an output rate "
                             f"above {self.sensor_paths.mode[1] / 0.45:g} Hz, got {self.output_rate:g} Hz")

    @classmethod
    def for_bench(cls, bench: Bench, speed: float | None = None, *, realisations: int = 64, cycles: int = 8,
                  sensor_paths: bool = True, seed: int = 1) -> EnsembleSettings:
        """The settings of ``bench``'s theory at commanded motor ``speed`` (rad/s; default the bench's):
        features, kept curves' filter and model output rate resolved from the bench's own kinematics
        and sensor chain (``measurement.scaling.resolve_analysis``), each realisation seen through a
        mount drawn around its bands (``sensor_paths``; ``PathSpread.around``). For the test bed at its
        1 Hz these are the defaults, ``EnsembleSettings()``."""
        a = resolve_analysis(bench, speed)
        return cls(realisations=realisations, cycles=cycles, seed=seed, output_rate=a.output_rate,
                   curve_filter=a.curve_filter, features=a.features,
                   sensor_paths=PathSpread.around(a.features) if sensor_paths else None)

    @classmethod
    def from_dict(cls, data: dict) -> EnsembleSettings:
        """The inverse of ``asdict`` (JSON lists back to tuples); a file of a version before drawn
        sensor paths holds none (its realisations saw the model's acceleration as it is)."""
        return cls(**{**data, "features": FeatureSpec.from_dict(data["features"]),
                      "sensor_paths": PathSpread.from_dict(data.get("sensor_paths"))})


@dataclass(frozen=True)
class EnsembleSize:
    """How much theory to build, before the bench is known: realisations per state, settled cycles per
    realisation, whether each sees a drawn sensor path. :meth:`resolve` gives a bench's settings at a
    speed (``EnsembleSettings.for_bench``); an explicit ``EnsembleSettings`` is used as it is."""

    realisations: int = 64
    cycles: int = 8
    sensor_paths: bool = True

    def resolve(self, bench: Bench, speed: float | None = None) -> EnsembleSettings:
        return EnsembleSettings.for_bench(bench, speed, realisations=self.realisations, cycles=self.cycles,
                                          sensor_paths=self.sensor_paths)


def resolve_settings(settings: EnsembleSettings | EnsembleSize | None, bench: Bench,
                     speed: float | None = None) -> EnsembleSettings:
    """``settings`` as they are, or (an :class:`EnsembleSize`, None: the default size) resolved for
    ``bench`` at ``speed``."""
    if isinstance(settings, EnsembleSettings):
        return settings
    return (settings or EnsembleSize()).resolve(bench, speed)


@dataclass(frozen=True)
class Ensemble:
    """One state's ensemble: features (M, C, p), filtered curves (M, C, grid), peaks (M, C)."""

    state: str
    settings: EnsembleSettings
    features: np.ndarray
    curves: np.ndarray
    peaks: np.ndarray
    speed: float  # commanded motor speed (rad/s)
    failures: tuple[str, ...] = ()  # realisations that failed (SimulationError text)

    @property
    def realisations(self) -> int:
        return int(self.features.shape[0])

    def band(self, lo: float = 5.0, hi: float = 95.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per crank angle of the curve grid: (low percentile, median, high percentile) over all cycles."""
        flat = self.curves.reshape(-1, self.curves.shape[-1])
        return tuple(np.percentile(flat, [lo, 50.0, hi], axis=0))


def _state_key(state: WearState) -> dict:
    return {"name": state.name, "clearances": {j: round(c, 12) for j, c in sorted(state.clearances.items())},
            "surfaces": {j: file_digest(p) for j, p in sorted(state.surfaces.items())}}


def realisation_summary(bench: Bench, state: WearState, seed: int, *, speed: float,
                        settings: EnsembleSettings) -> dict[str, np.ndarray]:
    """Simulate one realisation, see it through its drawn sensor path (``settings.sensor_paths``, if any)
    and reduce it to per-cycle features, curves and peaks (a worker task)."""
    from wearbench.model.realisation import simulate_state

    run = simulate_state(bench, state, seed, revolutions=settings.cycles + 1.0, settle=settings.settle,
                         speed=speed, output_rate=settings.output_rate)
    acc = run.acc if settings.sensor_paths is None else settings.sensor_paths.apply(run.acc, settings.output_rate, seed)
    feats = cycle_features(run.t, run.crank, acc, settings.features)
    curves, peaks = cycle_curves(run.t, run.crank, acc, grid=settings.grid,
                                 filter_spec=parse_filter(settings.curve_filter, remove_bias=False))
    n = min(feats.cycles, curves.shape[0], settings.cycles)
    return {"features": feats.values[:n], "curves": curves[:n], "peaks": peaks[:n]}


def realisation_revolutions(settings: EnsembleSettings) -> float:
    """Motor revolutions one realisation of ``settings`` simulates (settling included): its cost."""
    return settings.settle + settings.cycles + 1.0


def ensembles_key(bench: Bench, states: Sequence[WearState], speed: float, settings: EnsembleSettings) -> str:
    """Content address of a set of ensembles (also keys shipped precomputed ones)."""
    from wearbench.compute import task_key

    return task_key("ensembles", bench_key(bench), asdict(bench.tolerances), [_state_key(s) for s in states],
                    round(speed, 9), asdict(settings))


def realisation_keys(bench: Bench, states: Sequence[WearState], speed: float,
                     settings: EnsembleSettings) -> list[str]:
    """Result-cache keys of the realisations :func:`build_ensembles` runs, state by state, seed by seed.
    A realisation is its seed and how it is run: ensembles of other sizes or first seeds share it."""
    from wearbench.compute import task_key

    physics = bench_key(bench)
    how = {k: v for k, v in asdict(settings).items() if k not in ("realisations", "seed")}
    return [task_key("ensemble-realisation", physics, asdict(bench.tolerances), _state_key(state), settings.seed + i,
                     round(speed, 9), how) for state in states for i in range(settings.realisations)]


def sensor_paths_text(settings: EnsembleSettings) -> str:
    """The sensor path ensembles of ``settings`` assume, in words (their artefact's record)."""
    if settings.sensor_paths is None:
        return "none (the model's acceleration as it is)"
    lo, hi = settings.sensor_paths.mode
    return f"drawn per realisation (a mount mode {lo:g}-{hi:g} Hz)"


def build_ensembles(bench: Bench, states: Sequence[WearState], *, speed: float | None = None,
                    settings: EnsembleSettings | EnsembleSize | None = None, compute: Compute = DEFAULT,
                    cache: bool = True, shipped: bool = True, label: str = "theory ensembles") -> dict[str, Ensemble]:
    """Ensembles of every candidate ``state`` of ``bench`` at commanded motor ``speed`` (rad/s).

    Precomputed ensembles shipped for the bench are used (``shipped``) when their content key matches
    (same physics, states, speed, settings and model source); otherwise all realisations of all states
    go to the compute layer as one batch. A realisation that fails numerically is reported in
    ``Ensemble.failures``; a state with fewer than 3 good realisations raises, naming the failures.
    """
    from wearbench.compute import Task, TaskFailure
    from wearbench.compute.cost import Cost
    from wearbench.model.surfaces import JointSurfaces

    speed = bench.speed if speed is None else float(speed)
    settings = resolve_settings(settings, bench, speed)
    if not states:
        raise ValueError(f"{bench.name}: no candidate states (give [[state]] tables or --candidates)")
    for state in states:  # a bad surface file fails here, not in every realisation
        for joint, surface in state.surfaces.items():
            try:
                JointSurfaces.load(surface)
            except (OSError, ValueError) as exc:
                raise ValueError(f"candidate state {state.name!r}, joint {joint}: {exc}") from None
    if shipped and cache:
        found = artefacts.shipped("ensembles", bench.name, ensembles_key(bench, states, speed, settings))
        if found is not None:
            return _from_arrays(found[1])
    tasks, owners = [], []
    keys = iter(realisation_keys(bench, states, speed, settings))
    for state in states:
        for i in range(settings.realisations):
            seed = settings.seed + i
            tasks.append(Task(realisation_summary, {"bench": bench, "state": state, "seed": seed, "speed": speed,
                                                    "settings": settings}, next(keys), f"{state.name} #{i}",
                              realisation_revolutions(settings)))
            owners.append(state.name)
    middle = states[len(states) // 2]  # priced on a middle state: worn surfaces cost more than new ones
    results = compute.run(tasks, label=label, cache=cache, cost=Cost(bench, middle, speed, settings.output_rate,
                                                                     "realisations"))
    out: dict[str, Ensemble] = {}
    for state in states:
        mine = [r for r, o in zip(results, owners, strict=True) if o == state.name]
        good = [r for r in mine if not isinstance(r, TaskFailure)]
        failed = tuple(f"{r.label}: {r.error}" for r in mine if isinstance(r, TaskFailure))
        if len(good) < 3:
            raise RuntimeError(f"ensemble {state.name!r}: only {len(good)} of {len(mine)} realisations succeeded; "
                               + "; ".join(failed[:3]))
        c = min(g["features"].shape[0] for g in good)
        out[state.name] = Ensemble(state.name, settings, np.stack([g["features"][:c] for g in good]),
                                   np.stack([g["curves"][:c] for g in good]), np.stack([g["peaks"][:c] for g in good]),
                                   speed, failed)
    return out


MIN_REALISATIONS = 4  # identification fits each state without one realisation at a time (>= 3 left)


def save_ensembles(ensembles: Mapping[str, Ensemble], path: str | Path, *, key: str, bench: Bench,
                   states: Sequence[WearState]) -> Path:
    """Write ensembles to one artefact file (float32 curves) keyed ``key`` (:func:`ensembles_key`), naming
    the bench, speed and sensor path they were built for and the candidate states' keys, which
    :func:`check_ensembles_fit` checks before a session uses them."""
    first = next(iter(ensembles.values()))
    about = artefacts.About.of("ensembles", key, bench, first.speed, sensor_paths_text(first.settings))
    arrays: dict[str, np.ndarray] = {"states": np.array(list(ensembles)),
                                     "candidates": np.array(json.dumps([_state_key(s) for s in states]))}
    for i, e in enumerate(ensembles.values()):
        arrays[f"features_{i}"] = e.features
        arrays[f"curves_{i}"] = e.curves.astype(np.float32)
        arrays[f"peaks_{i}"] = e.peaks
        arrays[f"meta_{i}"] = np.array(json.dumps({"speed": e.speed, "failures": list(e.failures),
                                                   "settings": asdict(e.settings)}))
    return artefacts.write(path, about, arrays)


def _from_arrays(data: Mapping[str, np.ndarray]) -> dict[str, Ensemble]:
    out = {}
    for i, name in enumerate(data["states"]):
        meta = json.loads(str(data[f"meta_{i}"]))
        settings = EnsembleSettings.from_dict(meta["settings"])
        out[str(name)] = Ensemble(str(name), settings, data[f"features_{i}"], data[f"curves_{i}"].astype(float),
                                  data[f"peaks_{i}"], float(meta["speed"]), tuple(meta["failures"]))
    return out


def load_ensembles(path: str | Path, *, key: str | None = None) -> dict[str, Ensemble] | None:
    """Ensembles saved by :func:`save_ensembles`; None when ``key`` is given and differs (stale).
    A file that is not one (another artefact, another .npz, a cut file) raises one ArtefactError."""
    found = artefacts.read(path, "ensembles", key=key)
    if found is None:
        return None
    try:
        return _from_arrays(found[1])
    except (KeyError, ValueError, TypeError) as exc:
        raise artefacts.ArtefactError(f"{path}: an ensembles file missing or damaging {exc}") from None


def check_ensembles_fit(path: str | Path, ensembles: Mapping[str, Ensemble], *, bench: Bench | None,
                        states: Sequence[WearState] | None, speed: float, session: str) -> None:
    """Refuse (one ArtefactError line naming the mismatch) ensembles from ``path`` that do not fit a
    session of ``bench`` commanded at ``speed`` with candidate ``states`` (None: not known, unchecked)."""
    path = Path(path)
    about = artefacts.read_about(path, "ensembles")
    first = next(iter(ensembles.values()))
    if first.realisations < MIN_REALISATIONS:
        raise artefacts.ArtefactError(f"{path}: {first.realisations} realisations per state; identification needs "
                                      f"at least {MIN_REALISATIONS} (wearbench ensemble --realisations)")
    about.check(path, bench=bench, speed=speed, session=session)
    if states is not None:
        with np.load(path, allow_pickle=False) as data:
            built_keys = json.loads(str(data["candidates"]))
        if [_state_key(s) for s in states] != built_keys:
            built = [s["name"] for s in built_keys]
            asked = [s.name for s in states]
            what = "other clearances or worn surfaces" if built == asked else f"{asked}"
            raise artefacts.ArtefactError(f"{path}: built for the candidate states {built}; session {session}'s "
                                          f"candidates (--candidates, else its bench's [[state]] tables) are {what}")
