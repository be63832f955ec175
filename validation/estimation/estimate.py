"""Clearance and wear as estimates with credible intervals: the posterior over a continuum of states.

Parameters: the radial clearance ``c`` shared by the bench's clearance joints (the test bed's A and
B are made alike) and the wear as cycles run ``N`` along the bench's own Archard trajectory: the
surfaces that the wear model (``wearbench.model.wear_stages``) predicts after ``N`` cycles from
clearance ``c`` at the bench's speed. The ``[tolerances]`` stay nuisance parameters as in the
ensembles, and so does the sensor path (``sensor_path.py``).

Method (an emulator of the ensemble statistics over the parameter box, chosen because the
likelihood of ``identify`` then carries over unchanged, and a 2-D grid is exact and fast for two
parameters; an MCMC or a neural estimator adds nothing there):

1. **Design.** A grid of design points ``clearances x cycles`` (cycles equally spaced from 0, one
   wear stage apart). Per design clearance one wear run on the compute layer gives the surfaces at
   every design ``N`` (cached by content); per design point one theory ensemble (cached by content,
   ``ensemble.build_ensembles``). ``N`` between design points is interpolated in the *features*,
   not in the surfaces: the features move smoothly with wear, surfaces worn partway are not
   linear in ``N`` where the contact zone moves. Together the design's ensembles are the estimator
   artefact, keyed like the ensembles (:func:`estimator_key`; shipped ones: ``artefacts.shipped_path``).
   That one wear run per clearance is one wear realisation; the spread between realisations (more
   wear runs of drawn benches, ``spread.py``) is measured beside it (:func:`with_spread`) and kept in
   a sidecar file.
2. **Statistics.** ``identify.fit_states`` over the design points as if they were candidate states:
   pooled between-bench and cycle-to-cycle covariances, the sensor path marginalised, and the
   temperature that calibrates the likelihood on held-out realisations. The feature mean between
   design points is a tensor polynomial in (c, N) (degree up to 4 in ``c``, through the default
   design's five clearances, and up to 2 in ``N``) fitted to the design points' means; its residual
   variance is added to the covariance as the emulator's error. The design points share their
   realisations' seeds (the same benches at every point: differences between points are precise),
   so a seed's deviation is common to the points (correlation 0.7-0.8 measured on the shipped
   design's impact bands) and the fit's residual holds little of the design means' sampling error:
   it is not subtracted (it was, and zeroed the emulator error). The common part is in the
   covariance as the ensemble mean's error (``StateStatistics.covariance``).
3. **Posterior** on a grid over the design box (uniform prior), tempered as ``identify`` tempers;
   marginal medians, 50 % and 90 % credible intervals of ``c``, ``N`` and the wear depth (the
   largest clearance growth of any joint, its bearing's and journal's deepest points added,
   interpolated from the wear runs: what a clearance limit is checked against). With a wear spread,
   its covariance at the posterior's cycles run joins the likelihood's (one covariance over the grid,
   :meth:`EstimatorModel.log_posterior`), and the depth draws on every run's. Intervals are
   central, or one-sided from an end of the range where the posterior piles there
   (:meth:`Interval.from_weights`: the shortest 90 % interval then reaches that end; "at most" /
   "at least"), and say which (``Interval.kind``).
4. **Consistency**: the session's smallest distance over the grid against the same statistic of the
   design's own realisations (a gamma fitted by moments); below ``consistency`` the answer is "no
   parameter value explains it".
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy import linalg, optimize, special, stats
from wearbench.bench.schema import Bench, WearState
from wearbench.bench.units import parse_quantity
from wearbench.compute.options import DEFAULT, Compute
from wearbench.validation.estimation.spread import (
    SpreadDesign,
    WearSpread,
    load_spread,
    measure_spread,
    save_spread,
    spread_key,
    spread_path,
    spread_seed,
)
from wearbench.validation.inference import artefacts
from wearbench.validation.inference.ensemble import (
    Ensemble,
    EnsembleSettings,
    build_ensembles,
    realisation_revolutions,
    sensor_paths_text,
)
from wearbench.validation.inference.identify import (
    FLAT,
    IdentifyOptions,
    default_sensor,
    gamma_by_moments,
    prior_distance,
    state_statistics,
    variance_floor,
)
from wearbench.validation.inference.sensor_path import SensorPath
from wearbench.validation.inference.statistics import StateStatistics
from wearbench.validation.measurement.features import CycleFeatures, FeatureSpec

__all__ = ["INTERVAL_KINDS", "DesignRequest", "Estimate", "Estimator", "EstimatorDesign", "EstimatorModel", "Interval",
           "build_estimator", "check_design_values", "design_clearances", "design_cycles", "estimate_features",
           "estimator_key", "fit_estimator", "fmt_kcycles", "fmt_mm", "fmt_um", "load_estimator", "predictive_band",
           "resolve_design", "save_estimator"]

NO_VALUE = "no parameter value explains it"
SHORT_SESSION = 5  # complete crank cycles below which an estimate says the session is short (a window's length)
PRIOR_ONLY = "the session's evidence does not move the estimate from its prior"


@dataclass(frozen=True)
class EstimatorDesign:
    """Design points: every clearance (m, shared by the clearance joints) x every cycles-run value
    (equally spaced from 0: one wear stage apart); ensembles of ``settings`` at each."""

    clearances: tuple[float, ...] = (0.25e-3, 0.35e-3, 0.45e-3, 0.55e-3, 0.65e-3)
    cycles: tuple[float, ...] = (0.0, 200_000.0, 400_000.0, 600_000.0)
    settings: EnsembleSettings = field(default_factory=lambda: EnsembleSettings(realisations=48))

    def __post_init__(self) -> None:
        c, n = np.asarray(self.clearances, float), np.asarray(self.cycles, float)
        if c.size < 2 or np.any(np.diff(c) <= 0) or c[0] <= 0:
            raise ValueError(f"estimator design: clearances = {self.clearances}: expected at least two increasing "
                             "positive values (m)")
        if n.size < 2 or n[0] != 0 or not np.allclose(np.diff(n), n[1]) or n[1] <= 0:
            raise ValueError(f"estimator design: cycles = {self.cycles}: expected at least two values equally "
                             "spaced from 0 (one wear stage apart)")
        # 12 significant digits: "0.45mm" typed (0.45 * 1e-3 = 0.00045000000000000004) keys as 0.45e-3 does
        object.__setattr__(self, "clearances", tuple(float(f"{v:.12g}") for v in c))
        object.__setattr__(self, "cycles", tuple(float(f"{v:.12g}") for v in n))

    @classmethod
    def small(cls, bench: Bench | None = None, speed: float | None = None) -> EstimatorDesign:
        """A small design for a first look (the demo's while no shipped estimator fits): the default
        design's lowest, middle and highest clearance x cycles run 0, one and two wear stages, 3
        realisations x 4 cycles each (for the test bed 0.25, 0.45, 0.65 mm x 0, 200,000, 400,000; about 2
        min of CPU). Coarse: 3 x 3 points fit the emulator exactly, so its own error comes from
        leave-one-out. ``bench``: that bench's (:meth:`for_bench`), else the test bed's values."""
        if bench is not None:
            return cls.for_bench(bench, speed, small=True)
        return cls((0.25e-3, 0.45e-3, 0.65e-3), (0.0, 200_000.0, 400_000.0), EnsembleSettings(realisations=3, cycles=4))

    @classmethod
    def for_bench(cls, bench: Bench, speed: float | None = None, *, realisations: int | None = None,
                  ensemble_cycles: int | None = None, clearances: Sequence[float] | None = None,
                  cycles: Sequence[float] | None = None, small: bool = False) -> EstimatorDesign:
        """``bench``'s design at commanded motor ``speed`` (rad/s; default the bench's), each value
        given here kept, the others from the bench (:func:`design_clearances`, :func:`design_cycles`:
        its nominal and candidate clearances and its ``[wear]`` stage; the ensembles' settings
        resolved from its kinematics and sensor chain, ``EnsembleSettings.for_bench``), 48
        realisations x 8 cycles; ``small``: :meth:`small`'s sizes (3 clearances x 3 cycles-run values,
        3 realisations x 4 cycles). For the test bed at its speed: ``EstimatorDesign()``. Values that
        do not fit the bench raise one ValueError naming the option (``--design-clearances``, ...)."""
        grid = design_clearances(bench)
        runs = design_cycles(bench)
        if small:
            grid, runs = (grid[0], grid[2], grid[4]), runs[:3]
        grid = tuple(clearances) if clearances is not None else grid
        runs = tuple(cycles) if cycles is not None else runs
        check_design_values(bench, grid, runs)
        settings = EnsembleSettings.for_bench(bench, speed, realisations=realisations or (3 if small else 48),
                                              cycles=ensemble_cycles or (4 if small else 8))
        return cls(grid, runs, settings)

    @classmethod
    def parse(cls, clearances: str, cycles: str, *, realisations: int = 48,
              ensemble_cycles: int = 8) -> EstimatorDesign:
        """A design from text as a user types it: ``"0.25mm,0.45mm,0.65mm"``, ``"0,200000,400000"``
        (the ensembles' settings the test bed's; ``DesignRequest.parse`` for any bench's)."""
        request = DesignRequest.parse(clearances, cycles, realisations=realisations, ensemble_cycles=ensemble_cycles)
        return cls(request.clearances, request.cycles, EnsembleSettings(realisations=realisations,
                                                                       cycles=ensemble_cycles))

    def state(self, i: int, j: int, surfaces: Mapping[str, Path], joints: Sequence[str]) -> WearState:
        c, n = self.clearances[i], self.cycles[j]
        return WearState(point_name(c, n), {jn: c for jn in joints}, dict(surfaces))

    def to_dict(self) -> dict:
        return {"clearances": list(self.clearances), "cycles": list(self.cycles),
                "settings": {**asdict(self.settings), "features": self.settings.features.to_dict()}}


def design_clearances(bench: Bench) -> tuple[float, ...]:
    """The default design's five clearances (m) for ``bench``: equally spaced over the span of its
    nominal clearances and its ``[[state]]``s' (at least up to twice the smallest: a joint's clearance
    about doubles over its useful life, the test bed's 0.3 mm to 0.6 mm), widened by a sixth of the
    span at each end and kept inside half the smallest bearing radius. The test bed's 0.3 and 0.6 mm
    give 0.25, 0.35, 0.45, 0.55 and 0.65 mm."""
    joints = bench.clearance_joints
    if not joints:
        raise ValueError(f"{bench.name}: no clearance joints: nothing to estimate")
    values = [j.clearance.radial_clearance for j in joints]
    values += [c for s in bench.states for c in s.clearances.values()]
    lo, hi = min(values), max(values)
    hi = max(hi, 2 * lo)
    margin = (hi - lo) / 6
    top = 0.5 * min(j.clearance.bearing_radius for j in joints)
    grid = np.linspace(max(lo - margin, lo / 2), min(hi + margin, top), 5)
    return tuple(float(f"{v:.12g}") for v in grid)


def design_cycles(bench: Bench) -> tuple[float, ...]:
    """The default design's cycles run for ``bench``: 0 and three of its ``[wear]`` stages
    (``cycles_per_stage`` x ``stage_scale``; the test bed's 0, 200,000, 400,000, 600,000)."""
    stage = float(bench.wear.cycles_per_stage * bench.wear.stage_scale)
    return (0.0, stage, 2 * stage, 3 * stage)


def check_design_values(bench: Bench, clearances: Sequence[float], cycles: Sequence[float]) -> None:
    """Refuse (one ValueError naming the option) design values ``bench`` cannot take: clearances at
    least two, increasing, positive and inside its smallest bearing radius; cycles run at least two,
    from 0, equally spaced (one wear stage apart)."""
    c, n = np.asarray(clearances, float), np.asarray(cycles, float)
    text = ",".join(f"{v * 1e3:g}mm" for v in c)
    if c.size < 2 or np.any(np.diff(c) <= 0) or not np.all(np.isfinite(c)) or c[0] <= 0:
        raise ValueError(f"--design-clearances {text}: expected at least two increasing positive clearances")
    joints = bench.clearance_joints
    radius = min((j.clearance.bearing_radius for j in joints), default=np.inf)
    if c[-1] >= radius:
        raise ValueError(f"--design-clearances {text}: expected clearances below {bench.name}'s smallest bearing "
                         f"radius {radius * 1e3:g} mm")
    ntext = ",".join(f"{v:.0f}" for v in n)
    if (n.size < 2 or not np.all(np.isfinite(n)) or n[0] != 0 or n[1] <= 0
            or not np.allclose(np.diff(n), n[1])):
        raise ValueError(f"--design-cycles {ntext}: expected at least two cycles-run values equally spaced from 0 "
                         "(one wear stage apart), e.g. 0,200000,400000,600000")


@dataclass(frozen=True)
class DesignRequest:
    """What a command asks of an estimator's design before the bench is known (each None: the bench's
    default, :meth:`EstimatorDesign.for_bench`); :meth:`resolve` gives the bench's design."""

    clearances: tuple[float, ...] | None = None
    cycles: tuple[float, ...] | None = None
    realisations: int | None = None
    ensemble_cycles: int | None = None
    small: bool = False

    @classmethod
    def parse(cls, clearances: str | None, cycles: str | None, *, realisations: int | None = None,
              ensemble_cycles: int | None = None, small: bool = False) -> DesignRequest:
        """A request from text as a user types it: ``"0.25mm,0.45mm,0.65mm"`` (a bare number in mm),
        ``"0,200000,400000"`` (None: the bench's); one ValueError naming the option otherwise."""
        c = n = None
        if clearances is not None:
            try:
                c = tuple(parse_quantity(v, "length", bare_unit="mm") for v in clearances.split(","))
            except ValueError as exc:
                raise ValueError(f"--design-clearances {clearances!r}: {exc}") from None
        if cycles is not None:
            try:
                n = tuple(float(v.replace("_", "")) for v in cycles.split(","))
            except ValueError:
                raise ValueError(f"--design-cycles {cycles!r}: expected cycles-run numbers separated by commas, e.g. "
                                 "0,200000,400000") from None
        return cls(c, n, realisations, ensemble_cycles, small)

    def resolve(self, bench: Bench, speed: float | None = None) -> EstimatorDesign:
        return EstimatorDesign.for_bench(bench, speed, realisations=self.realisations,
                                         ensemble_cycles=self.ensemble_cycles, clearances=self.clearances,
                                         cycles=self.cycles, small=self.small)


def resolve_design(design: EstimatorDesign | DesignRequest | None, bench: Bench,
                   speed: float | None = None) -> EstimatorDesign:
    """``design`` as it is, or (a :class:`DesignRequest`, None: the default) resolved for ``bench`` at
    ``speed``."""
    if isinstance(design, EstimatorDesign):
        return design
    return (design or DesignRequest()).resolve(bench, speed)


def point_name(c: float, n: float) -> str:
    return f"{c * 1e3:.4g} mm after {n:,.0f} cycles"


@dataclass(frozen=True)
class Estimator:
    """The artefact: the design and its simulations (per design point an ensemble's features), and
    the worn depth of the wear runs; fitted in seconds by :func:`fit_estimator`."""

    bench: str
    key: str
    design: EstimatorDesign
    features: np.ndarray  # (clearances, cycles, M, C, p)
    depth: np.ndarray  # (clearances, cycles) wear depth: largest bearing + journal max depth of any joint (m)
    speed: float
    path: Path | None = field(default=None, compare=False)  # the file it was loaded from (its move beside it)
    about: artefacts.About | None = field(default=None, compare=False)  # its record, when loaded from a file
    spread: WearSpread | None = field(default=None, compare=False)  # between wear realisations (``spread.py``)

    @property
    def spec(self) -> FeatureSpec:
        return self.design.settings.features


# ---- building ---------------------------------------------------------------------------------


def wear_trajectory(bench: Bench, clearance: float, stages: int, stage_cycles: float, speed: float,
                    seed: int | None = None) -> list[dict[str, tuple[np.ndarray, np.ndarray, float]]]:
    """The surfaces after each of ``stages`` wear stages from ``clearance`` (a compute-layer task):
    per stage {joint: (bearing depth, journal depth, cycles)}; ``seed``: of the bench drawn from the
    tolerances (``realisation.draw_realisation``), its true speed and random start; None: the nominal bench."""
    from wearbench.model import build_scene
    from wearbench.model.realisation import draw_realisation, realisation_start
    from wearbench.model.wear_stages import StagePlan, run_stages

    plan = StagePlan.from_bench(bench, stages=stages, stage_cycles=stage_cycles)
    clearances = {j.name: clearance for j in bench.clearance_joints}
    start = None
    if seed is not None:  # a bench as built wears its own way
        real = draw_realisation(bench, seed)
        bench, speed = real.bench, speed * real.speed_scale
        start = realisation_start(real, build_scene(bench.with_speed(speed), clearances=clearances), speed)
    run = run_stages(bench, plan, clearances=clearances, speed=speed, start=start)
    return [{j: (s.bearing, s.journal, s.cycles) for j, s in st.surfaces.items()} for st in run.stages]


def wear_revolutions(stages: int) -> float:
    """Motor revolutions a wear run of ``stages`` stages simulates, at least (``wear_stages.StagePlan``'s
    settling and its least updates per stage, one revolution each): what it costs, about."""
    from wearbench.model.wear_stages import StagePlan

    plan = StagePlan()
    return float(plan.settle + stages * plan.min_updates * plan.update_revolutions)


def estimator_key(bench: Bench, design: EstimatorDesign, speed: float) -> str:
    """Content address of an estimator (also keys a shipped one): bench physics and tolerances, the
    wear settings, the design, the speed and the model source."""
    from wearbench.bench.content import bench_key
    from wearbench.compute import task_key

    return task_key("estimator", bench_key(bench), asdict(bench.tolerances), asdict(bench.wear), design.to_dict(),
                    round(speed, 9))


def default_spread(design: EstimatorDesign) -> SpreadDesign:
    """The wear-run spread a design gets unless asked otherwise: three drawn benches' wear runs per
    design clearance, 12 realisations of each worn point (paired with the design's first 12 seeds);
    none for a design of fewer than 12 realisations (a first look, :meth:`EstimatorDesign.small`)."""
    spread = SpreadDesign()
    return spread if design.settings.realisations >= spread.realisations else SpreadDesign(0)


def check_spread(design: EstimatorDesign, spread: SpreadDesign) -> None:
    """Refuse (one ValueError naming the option) a spread ``design`` cannot pair: its realisations run
    with the design's first seeds, so it needs at least as many in the design."""
    if spread.runs and spread.realisations > design.settings.realisations:
        raise ValueError(f"--wear-runs {spread.runs}: the spread pairs {spread.realisations} realisations per worn point "
                         f"with the design's first seeds: expected --realisations of at least {spread.realisations}")


def spread_plan(design: EstimatorDesign, spread: SpreadDesign) -> list[tuple[str, int, float]]:
    """What a spread simulates, as ``compute.cost.plan_line`` parts (noun, count, revolutions of each)."""
    if not spread.runs:
        return []
    nc, nn = len(design.clearances), len(design.cycles)
    return [("spread wear runs", nc * spread.runs, wear_revolutions(nn - 1)),
            ("spread realisations", nc * spread.runs * (nn - 1) * spread.realisations,
             realisation_revolutions(replace(design.settings, realisations=spread.realisations)))]


def build_estimator(bench: Bench, design: EstimatorDesign | DesignRequest | None = None, *,
                    speed: float | None = None, compute: Compute = DEFAULT, cache: bool = True, shipped: bool = True,
                    label: str = "estimator", spread: SpreadDesign | None = None) -> Estimator:
    """The estimator of ``bench``: a shipped one when its key matches, else the design's wear runs
    (one per clearance) and ensembles (one per design point) on the compute layer, cached by content;
    with the spread between wear realisations of ``spread`` (default :func:`default_spread`; ``spread.py``),
    shipped beside it or built. A shipped estimator of the same design with fewer realisations holds
    the first of them (realisation i is seed + i at every size): only the seeds it lacks are simulated."""
    from wearbench.bench.content import cache_folder
    from wearbench.compute import Task, TaskFailure, task_key
    from wearbench.compute.cost import plan_line

    speed = bench.speed if speed is None else float(speed)
    joints = [j.name for j in bench.clearance_joints]
    if not joints:
        raise ValueError(f"{bench.name}: no clearance joints: nothing to estimate")
    design = resolve_design(design, bench, speed)
    spread = default_spread(design) if spread is None else spread
    check_spread(design, spread)  # before anything is simulated
    key = estimator_key(bench, design, speed)
    base, m0 = None, 0  # a shipped smaller estimator of this design and how many realisations it gives
    if shipped and cache and artefacts.shipped_path("estimator", bench.name).exists():
        found = load_estimator(artefacts.shipped_path("estimator", bench.name))
        if found.key == key:
            return with_spread(bench, found, spread, speed=speed, compute=compute, cache=cache, label=label)
        base, m0 = found, _first_realisations(bench, design, speed, found)
    stages, stage = len(design.cycles) - 1, design.cycles[1]
    wkeys = [task_key("estimator-wear", key, c) for c in design.clearances]
    settings = design.settings
    points = len(design.clearances) * len(design.cycles)
    if compute.progress:  # the whole plan, before the wear runs start
        compute.announce(plan_line(label, [("wear runs", len(design.clearances), wear_revolutions(stages)),
                                           ("realisations", points * (settings.realisations - m0),
                                            realisation_revolutions(settings)), *spread_plan(design, spread)],
                                   _cost(bench, design, speed), workers=compute.workers_known))
    runs = compute.run([Task(wear_trajectory, {"bench": bench, "clearance": c, "stages": stages, "stage_cycles": stage,
                                             "speed": speed}, k, f"wear {c * 1e3:.3g} mm", wear_revolutions(stages))
                      for c, k in zip(design.clearances, wkeys, strict=True)],
                     label=f"{label}: wear", cache=cache, cost=_cost(bench, design, speed, "wear runs"))
    failed = [r for r in runs if isinstance(r, TaskFailure)]
    if failed:
        raise RuntimeError(f"estimator {bench.name}: wear run failed: {failed[0]}")
    folder = cache_folder("estimator-surfaces")
    states, depth = [], np.zeros((len(design.clearances), len(design.cycles)))
    for i, (run, wk) in enumerate(zip(runs, wkeys, strict=True)):
        worn, depth[i] = _worn_states(design, i, run, wk, folder, joints)
        states += worn
    if m0 and not np.array_equal(base.depth, depth):
        m0 = 0  # its wear runs are not these: its realisations saw other surfaces
    settings = design.settings if not m0 else replace(design.settings, seed=design.settings.seed + m0,
                                                      realisations=design.settings.realisations - m0)
    ens = build_ensembles(bench, states, speed=speed, settings=settings, compute=compute, cache=cache, shipped=False,
                          label=f"{label}: ensembles")
    est = estimator_from_ensembles(bench.name, key, design, ens, depth, speed)
    est = replace(est, about=artefacts.About.of("estimator", key, bench, speed, sensor_paths_text(design.settings)))
    if m0:
        c = min(base.features.shape[3], est.features.shape[3])
        est = replace(est, features=np.concatenate([base.features[:, :, :, :c], est.features[:, :, :, :c]], axis=2))
    return with_spread(bench, est, spread, speed=speed, compute=compute, cache=cache, label=label, announce=False)


def _cost(bench: Bench, design: EstimatorDesign, speed: float, noun: str = "simulations"):
    """What a design's simulations cost, priced at its middle clearance."""
    from wearbench.compute.cost import Cost

    middle = WearState("design", dict.fromkeys([j.name for j in bench.clearance_joints],
                                               design.clearances[len(design.clearances) // 2]))
    return Cost(bench, middle, speed, design.settings.output_rate, noun)


def _worn_states(design: EstimatorDesign, i: int, run: list, run_key: str, folder: Path, joints: Sequence[str],
                 name: str = "") -> tuple[list[WearState], np.ndarray]:
    """The design points of clearance ``i`` on wear ``run`` (``wear_trajectory``'s stages; surface files
    kept in ``folder`` under ``run_key``) as states (named by :func:`point_name` and ``name``) and
    their wear depths."""
    from wearbench.model.surfaces import JointSurfaces

    states, depth = [], np.zeros(len(design.cycles))
    for j in range(len(design.cycles)):
        files = {}
        for jn, (b, jr, cyc) in (run[j - 1].items() if j else ()):
            path = folder / f"{run_key[:24]}_{jn}_{j}.npz"
            if not path.exists():
                JointSurfaces(b, jr, cyc, f"{point_name(design.clearances[i], design.cycles[j])}{name}").save(path)
            files[jn] = path
            depth[j] = max(depth[j], float(np.max(b)) + float(np.max(jr)))
        state = design.state(i, j, files, joints)
        states.append(replace(state, name=state.name + name))
    return states, depth


def with_spread(bench: Bench, est: Estimator, spread: SpreadDesign, *, speed: float, compute: Compute = DEFAULT,
                cache: bool = True, label: str = "estimator", announce: bool = True) -> Estimator:
    """``est`` with the spread between wear realisations of ``spread`` (none: ``spread.runs`` 0): the one
    it carries when its key matches, else ``spread.runs`` wear runs per design clearance of benches drawn
    with :func:`~wearbench.validation.estimation.spread.spread_seed` and ``spread.realisations`` of
    every worn point (the design's first seeds) on the compute layer, cached by content (``announce``:
    print its plan first)."""
    from wearbench.bench.content import cache_folder
    from wearbench.compute import Task, TaskFailure, task_key
    from wearbench.compute.cost import plan_line

    if not spread.runs:
        return replace(est, spread=None)
    key = spread_key(est.key, spread)
    if est.spread is not None and est.spread.key == key:
        return est
    d = est.design
    check_spread(d, spread)
    if announce and compute.progress:
        compute.announce(plan_line(f"{label}: wear spread", spread_plan(d, spread), _cost(bench, d, speed),
                                   workers=compute.workers_known))
    stages, joints = len(d.cycles) - 1, [j.name for j in bench.clearance_joints]
    cases = [(q, i, c, spread_seed(i, q)) for i, c in enumerate(d.clearances) for q in range(spread.runs)]
    wkeys = [task_key("estimator-spread-wear", est.key, c, s) for *_, c, s in cases]
    runs = compute.run([Task(wear_trajectory, {"bench": bench, "clearance": c, "stages": stages,
                                               "stage_cycles": d.cycles[1], "speed": speed, "seed": s}, k,
                             f"wear {c * 1e3:.3g} mm, bench {s}", wear_revolutions(stages))
                        for (*_, c, s), k in zip(cases, wkeys, strict=True)],
                       label=f"{label}: spread wear", cache=cache, cost=_cost(bench, d, speed, "wear runs"))
    failed = [r for r in runs if isinstance(r, TaskFailure)]
    if failed:
        raise RuntimeError(f"estimator {bench.name}: a wear run of the spread failed: {failed[0]}")
    folder = cache_folder("estimator-surfaces")
    nc, nn = len(d.clearances), len(d.cycles)
    states, depth, names = [], np.zeros((spread.runs, nc, nn)), {}
    for (q, i, _, s), run, wk in zip(cases, runs, wkeys, strict=True):
        worn, depth[q, i] = _worn_states(d, i, run, wk, folder, joints, f", bench {s}")
        names.update({(q, i, j): st.name for j, st in enumerate(worn) if j})
        states += worn[1:]  # 0 cycles: unworn surfaces, the reference's point
    settings = replace(d.settings, realisations=spread.realisations)
    ens = build_ensembles(bench, states, speed=speed, settings=settings, compute=compute, cache=cache, shipped=False,
                          label=f"{label}: spread ensembles")
    r, cyc = spread.realisations, min(e.features.shape[1] for e in ens.values())
    feats = np.array([[[ens[names[q, i, j]].features[:r, :cyc] for j in range(1, nn)] for i in range(nc)]
                      for q in range(spread.runs)])  # (runs, clearances, cycles - 1, R, C, p)
    return replace(est, spread=WearSpread(est.key, key, spread, d.cycles, measure_spread(est.features, feats), depth))


def _first_realisations(bench: Bench, design: EstimatorDesign, speed: float, est: Estimator) -> int:
    """How many of ``design``'s first realisations ``est`` holds: all of its own when it is ``design``
    with fewer realisations from the same first seed (by its key), all good, and at least 3 short of
    ``design`` (an ensemble's least); else 0."""
    m = est.features.shape[2]
    if not 0 < m <= design.settings.realisations - 3:
        return 0
    smaller = replace(design, settings=replace(design.settings, realisations=m))
    return m if est.key == estimator_key(bench, smaller, speed) else 0


def estimator_from_ensembles(bench: str, key: str, design: EstimatorDesign, ensembles: Mapping[str, Ensemble],
                             depth: np.ndarray, speed: float) -> Estimator:
    """An :class:`Estimator` from the design points' ensembles (named by :func:`point_name`)."""
    m = min(e.realisations for e in ensembles.values())
    c = min(e.features.shape[1] for e in ensembles.values())
    feats = np.stack([np.stack([ensembles[point_name(ci, nj)].features[:m, :c] for nj in design.cycles])
                      for ci in design.clearances])
    return Estimator(bench, key, design, feats, np.asarray(depth, float), float(speed))


def save_estimator(est: Estimator, path: str | Path) -> Path:
    """Write ``est`` as an artefact naming the bench, speed and sensor path it was built for (an
    estimator made by hand, not built from a bench, names no bench key); its wear spread, when it
    carries one, goes beside it with :func:`save_estimator_spread`."""
    return artefacts.write(path, _about(est), {"features": est.features, "depth": est.depth,
                                               "design": np.array(json.dumps(est.design.to_dict()))})


def save_estimator_spread(est: Estimator, path: str | Path) -> Path:
    """Write ``est``'s wear spread to ``path`` (``spread.spread_path`` of where ``est`` is saved)."""
    if est.spread is None:
        raise ValueError(f"estimator {est.bench}: no wear spread to save (built with --wear-runs 0)")
    return save_spread(est.spread, path, _about(est))


def _about(est: Estimator) -> artefacts.About:
    return est.about or artefacts.About("estimator", est.key, est.bench, "", est.speed,
                                        sensor_paths_text(est.design.settings))


def load_estimator(path: str | Path, *, key: str | None = None) -> Estimator | None:
    """An estimator saved by :func:`save_estimator`; None when ``key`` is given and differs (stale).
    A file that is not one (another artefact, another .npz, a session, a cut file) raises one
    ArtefactError naming it."""
    found = artefacts.read(path, "estimator", key=key)
    if found is None:
        return None
    about, data = found
    try:
        d = json.loads(str(data["design"]))
        design = EstimatorDesign(tuple(d["clearances"]), tuple(d["cycles"]),
                                 EnsembleSettings.from_dict(d["settings"]))
        est = Estimator(about.bench, about.key, design, data["features"], data["depth"], about.speed, Path(path),
                        about)
    except (KeyError, ValueError, TypeError) as exc:
        raise artefacts.ArtefactError(f"{path}: an estimator missing or damaging {exc}") from None
    beside = spread_path(path)
    return replace(est, spread=load_spread(beside, est.key)) if beside.is_file() else est


# ---- fitting ----------------------------------------------------------------------------------


def _basis(u: np.ndarray, v: np.ndarray, degrees: tuple[int, int]) -> np.ndarray:
    """Tensor monomials u^a v^b, a <= degrees[0], b <= degrees[1] (u, v scaled to [-1, 1])."""
    return np.stack([u ** a * v ** b for a in range(degrees[0] + 1) for b in range(degrees[1] + 1)], axis=-1)


def _loo_error(phi: np.ndarray, means: np.ndarray) -> np.ndarray:
    """Per feature, the emulator's error variance from predicting each design point's mean by the
    (minimum-norm) fit to the others, each squared error divided by 1 + the prediction weights'
    squared norm (the others' sampling error it carries)."""
    out = np.zeros(means.shape[1])
    for k in range(phi.shape[0]):
        rest = np.delete(np.arange(phi.shape[0]), k)
        w = phi[k] @ np.linalg.pinv(phi[rest])  # prediction weights on the other points' means
        out += (means[k] - w @ means[rest]) ** 2 / (1.0 + w @ w)
    return out / phi.shape[0]


@dataclass
class EstimatorModel:
    """A fitted estimator: the design's statistics, the mean emulator, and the grid."""

    estimator: Estimator
    stats: dict[str, StateStatistics]  # the design points as states (pooled covariances, sensor path)
    options: IdentifyOptions
    sensor: SensorPath | None
    temperature: float
    coef: np.ndarray  # (basis, p)
    degrees: tuple[int, int]
    discrepancy: np.ndarray  # (p,) emulator error variance
    grid_c: np.ndarray
    grid_n: np.ndarray
    grid_mean: np.ndarray  # (gc, gn, p)
    grid_depth: np.ndarray  # (gc, gn)
    null: tuple[float, float]
    reference: str  # the design point whose covariance (with its sensor nuisance) the grid uses
    run_depth: np.ndarray | None = None  # (runs, gc, gn): the wear spread's runs' depths (None: no spread)

    @property
    def spread(self) -> WearSpread | None:
        return self.estimator.spread

    def scaled(self, c: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        d = self.estimator.design
        lo, hi = d.clearances[0], d.clearances[-1]
        return (2 * (np.asarray(c) - lo) / (hi - lo) - 1, 2 * np.asarray(n) / d.cycles[-1] - 1)

    def mean(self, c: np.ndarray | float, n: np.ndarray | float) -> np.ndarray:
        """Emulated feature mean at clearance ``c`` (m) after ``n`` cycles (model columns)."""
        return _basis(*self.scaled(c, n), self.degrees) @ self.coef

    def covariance(self, cycles: float) -> np.ndarray:
        return self.stats[self.reference].covariance(cycles) + np.diag(self.discrepancy)

    def distances(self, xbar: np.ndarray, cycles: float, extra: np.ndarray | None = None) -> np.ndarray:
        """Squared Mahalanobis distance of a session mean over ``cycles`` to every grid point (gc, gn);
        ``extra``: a covariance (p, p) added to the tempered likelihood's (it is divided by the
        temperature here: ``temperature x`` the covariance is what the likelihood uses)."""
        cov = self.covariance(cycles) + (0 if extra is None else extra / self.temperature)
        chol = linalg.cholesky(cov, lower=True)
        d = (np.asarray(xbar, float) - self.grid_mean).reshape(-1, self.grid_mean.shape[-1])
        z = linalg.solve_triangular(chol, d.T, lower=True)
        return np.sum(z * z, axis=0).reshape(self.grid_mean.shape[:2])

    def log_posterior(self, xbar: np.ndarray, cycles: float, *, passes: int = 2) -> tuple[np.ndarray, np.ndarray]:
        """The tempered log posterior (gc, gn), normalised (uniform prior on the grid), of a session
        mean over ``cycles``, and its distances. With a wear spread, the spread at the cycles run the
        posterior gives (its weighted mean over the grid's columns) is added to the covariance, the
        posterior taken again, ``passes`` times: one covariance over the grid, so that how widely a
        session scatters about the emulated mean does not itself count as evidence of wear (a
        covariance growing with cycles run would, and would read wear from the reference run's
        smoothness)."""
        d2 = self.distances(xbar, cycles)
        logp = -0.5 * d2 / self.temperature
        logp -= special.logsumexp(logp)
        for _ in range(passes if self.spread is not None else 0):
            w = np.exp(logp).sum(axis=0)
            extra = sum(wk * self.spread.at(n) for wk, n in zip(w, self.grid_n, strict=True) if wk > 0)
            d2 = self.distances(xbar, cycles, extra)
            logp = -0.5 * d2 / self.temperature
            logp -= special.logsumexp(logp)
        return logp, d2

    def depth_values(self, posterior: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Wear depths and their weights under ``posterior`` (gc, gn): the reference run's depth at
        every grid point and, with a wear spread, every spread run's, the runs weighted alike."""
        if self.run_depth is None:
            return self.grid_depth.ravel(), posterior.ravel()
        runs = 1 + self.run_depth.shape[0]
        return (np.concatenate([self.grid_depth.ravel(), self.run_depth.ravel()]),
                np.tile(posterior.ravel(), runs) / runs)

    def log_likelihood(self, xbar: np.ndarray, cycles: float, c: float, n: float) -> float:
        """Untempered Gaussian log likelihood at one parameter value (what ranks candidate states)."""
        cov = self.covariance(cycles)
        chol = linalg.cholesky(cov, lower=True)
        z = linalg.solve_triangular(chol, np.asarray(xbar, float) - self.mean(c, n), lower=True)
        return float(-0.5 * (z @ z) - np.log(np.diag(chol)).sum() - 0.5 * z.size * np.log(2 * np.pi))


def fit_estimator(est: Estimator, options: IdentifyOptions | None = None, *, sensor: SensorPath | None = None,
                  grid: tuple[int, int] = (81, 61)) -> EstimatorModel:
    """Fit the design's statistics, the mean emulator, the grid and the consistency null
    (``options``: identification's, default ``IdentifyOptions()``; ``sensor``: a calibration)."""
    options = options or IdentifyOptions()
    d = est.design
    nc, nn = len(d.clearances), len(d.cycles)
    names = [point_name(c, n) for c in d.clearances for n in d.cycles]
    spec = est.spec
    sensor = sensor or default_sensor(spec, options)
    floor = variance_floor(spec, options)
    own = {nm: StateStatistics.fit(est.features[i, j], floor)
           for (i, j), nm in zip(np.ndindex(nc, nn), names, strict=True)}
    fitted = state_statistics(own, options.pooled, spec, sensor, slice(None))
    means = np.stack([fitted[nm].mean for nm in names])  # (D, p), the sensor prior's mean included
    cc, nn_ = np.meshgrid(d.clearances, d.cycles, indexing="ij")
    degrees = (min(4, nc - 1), min(2, nn - 1))
    lo, hi = d.clearances[0], d.clearances[-1]
    u, v = 2 * (cc.ravel() - lo) / (hi - lo) - 1, 2 * nn_.ravel() / d.cycles[-1] - 1
    phi = _basis(u, v, degrees)
    pinv = np.linalg.pinv(phi)
    coef = pinv @ means
    dof = phi.shape[0] - phi.shape[1]
    if dof > 0:
        discrepancy = np.sum((means - phi @ coef) ** 2, axis=0) / dof
    else:  # an exact fit (e.g. 3 x 3 points, quadratic): each point predicted from the others instead
        discrepancy = _loo_error(phi, means)
    gc = np.linspace(lo, hi, grid[0])
    gn = np.linspace(0.0, d.cycles[-1], grid[1])
    gu, gv = np.meshgrid(2 * (gc - lo) / (hi - lo) - 1, 2 * gn / d.cycles[-1] - 1, indexing="ij")
    basis = _basis(gu, gv, degrees)
    centre = names[(nc // 2) * nn + nn // 2]
    runs = None if est.spread is None else np.stack([_grid_depth(d, r, gc, gn) for r in est.spread.depth])
    model = EstimatorModel(est, fitted, options, sensor, 1.0, coef, degrees, discrepancy, gc, gn, basis @ coef,
                           _grid_depth(d, est.depth, gc, gn), (1.0, 1.0), centre, runs)
    # held-out realisations of the design: each one's distances to the grid with the emulator refitted
    # without it (its design point's mean moves; the covariances are kept), for the temperature and the
    # consistency null
    m_real, c_real = est.features.shape[2], est.features.shape[3]
    chol = linalg.cholesky(model.covariance(c_real), lower=True)
    whiten = lambda a: linalg.solve_triangular(chol, a.T, lower=True).T
    grid_w = whiten(model.grid_mean.reshape(-1, means.shape[1]))
    basis_w = basis.reshape(-1, basis.shape[-1])
    cell_c = np.abs(gc[:, None] - np.asarray(d.clearances)[None]).argmin(axis=0)
    cell_n = np.abs(gn[:, None] - np.asarray(d.cycles)[None]).argmin(axis=0)
    d2s, truth = [], []
    for k, (i, j) in enumerate(np.ndindex(nc, nn)):
        for r in range(m_real):
            x = est.features[i, j, r].mean(axis=0)
            moved = (x - est.features[i, j].mean(axis=(0, 1))) / (1 - m_real)  # the mean without r, less the mean
            grid_loo = grid_w + np.outer(basis_w @ pinv[:, k], whiten(moved[None])[0])  # whitening is linear
            d2 = np.sum((whiten(x[None])[0] - grid_loo) ** 2, axis=1)
            d2s.append(d2)
            truth.append(cell_c[i] * gn.size + cell_n[j])
    d2s_a, truth_a = np.asarray(d2s), np.asarray(truth)

    def log_loss(log_t: float) -> float:
        z = -0.5 * d2s_a / np.exp(log_t)
        return float(-np.mean(z[np.arange(len(truth_a)), truth_a] - special.logsumexp(z, axis=1)))

    model.temperature = float(np.exp(optimize.minimize_scalar(log_loss, bounds=(np.log(0.2), np.log(20.0)),
                                                              method="bounded").x))
    own_min = d2s_a.min(axis=1)
    model.null = gamma_by_moments(own_min)
    return model


def _grid_depth(design: EstimatorDesign, depth: np.ndarray, gc: np.ndarray, gn: np.ndarray) -> np.ndarray:
    """A wear run's depth (clearances, cycles) on the grid: linear in N along each design clearance,
    then linear in c."""
    along = np.stack([np.interp(gn, design.cycles, row) for row in depth])  # (nc, gn)
    return np.stack([np.interp(gc, design.clearances, along[:, k]) for k in range(gn.size)], axis=1)


# ---- estimating -------------------------------------------------------------------------------


INTERVAL_KINDS = ("central", "upper bound", "lower bound")


def fmt_mm(v: float) -> str:
    """A clearance (m) as an interval prints it: mm, three decimals."""
    return f"{v * 1e3:.3f}"


def fmt_kcycles(v: float) -> str:
    """Cycles run as an estimate's interval prints them: thousands."""
    return f"{v / 1e3:.0f}k"


def fmt_um(v: float) -> str:
    """A wear depth (m) as an interval prints it: micrometres, one decimal."""
    return f"{v * 1e6:.1f}"


@dataclass(frozen=True)
class Interval:
    """Posterior median and 50 % and 90 % credible intervals of one parameter (SI units).

    ``kind``: ``"central"``, equal tails (5-95 %, 25-75 %); ``"upper bound"``, one-sided from the
    lowest value the parameter can take ("at most": 0-90 %, 0-50 %), where the posterior piles at that
    end; ``"lower bound"``, one-sided to the highest ("at least": 10-100 %, 50-100 %)."""

    median: float
    lo50: float
    hi50: float
    lo90: float
    hi90: float
    kind: str = "central"

    def __post_init__(self) -> None:
        if self.kind not in INTERVAL_KINDS:
            raise ValueError(f"interval kind {self.kind!r}: expected one of {INTERVAL_KINDS}")

    def contains(self, x: float, level: int = 90) -> bool:
        lo, hi = (self.lo90, self.hi90) if level == 90 else (self.lo50, self.hi50)
        return lo <= x <= hi

    def map(self, f: Callable[[float], float]) -> Interval:
        """The interval of ``f`` of the parameter (``f`` increasing: quantiles map to quantiles)."""
        return Interval(*(float(f(v)) for v in (self.median, self.lo50, self.hi50, self.lo90, self.hi90)), self.kind)

    def text(self, fmt: Callable[[float], str] = lambda v: f"{v:.3g}", level: int = 90) -> str:
        """The interval in words: ``"lo-hi"``, ``"at most hi"`` or ``"at least lo"`` (values by ``fmt``)."""
        lo, hi = (self.lo90, self.hi90) if level == 90 else (self.lo50, self.hi50)
        if self.kind == "upper bound":
            return f"at most {fmt(hi)}"
        if self.kind == "lower bound":
            return f"at least {fmt(lo)}"
        return f"{fmt(lo)}-{fmt(hi)}"

    @classmethod
    def from_weights(cls, values: np.ndarray, weights: np.ndarray, *, edges: bool = False) -> Interval:
        """Quantiles of a distribution given on grid ``values`` by ``weights`` (piecewise linear CDF).

        ``edges``: the values span the range the parameter can take (a design box), and where the
        posterior piles at one end of it the interval is one-sided from that end: the shortest
        interval holding 90 % then reaches the end, and a central one would leave out the values most
        probable. The rule: one-sided where the shortest 90 % interval starts (or ends) at the end of
        the support and is shorter than the central one; central (5-95 %, 25-75 %) otherwise."""
        order = np.argsort(values, kind="stable")
        x, w = np.asarray(values, float)[order], np.asarray(weights, float)[order]
        keep = np.flatnonzero(w > 0)  # the support: an end of zero weight is no end the posterior reaches
        if keep.size:
            x, w = x[keep[0]:keep[-1] + 1], w[keep[0]:keep[-1] + 1]
        cdf = np.cumsum(w)
        cdf = cdf / cdf[-1]
        mid = cdf - 0.5 * w / w.sum()  # each grid value holds the mass of its cell, centred on it
        q = lambda p: np.interp(p, mid, x)
        central = cls(*(float(q(p)) for p in (0.5, 0.25, 0.75, 0.05, 0.95)))
        if not edges or x[-1] <= x[0]:
            return central
        start = np.linspace(0.0, 0.1, 201)
        widths = q(start + 0.9) - q(start)
        shortest, wide = widths.min(), (central.hi90 - central.lo90) * (1 - 1e-3)
        if widths[0] <= shortest * (1 + 1e-9) and widths[0] < wide:
            return cls(central.median, float(x[0]), central.median, float(x[0]), float(q(0.9)), "upper bound")
        if widths[-1] <= shortest * (1 + 1e-9) and widths[-1] < wide:
            return cls(central.median, central.median, float(x[-1]), float(q(0.1)), float(x[-1]), "lower bound")
        return central


@dataclass
class Estimate:
    """The answer for one session: marginal intervals, the joint posterior, the consistency test."""

    session: str
    cycles: int
    clearance: Interval  # m
    cycles_run: Interval  # cycles
    depth: Interval  # m, wear depth: largest clearance growth of any joint (bearing + journal deepest points)
    mode: tuple[float, float]  # (c m, N cycles) at the posterior's maximum
    correlation: float  # of c and N under the posterior
    p_value: float
    explains: bool
    verdict: str  # "c = ... mm, N = ..." or NO_VALUE
    sensor_path: str
    notes: list[str] = field(default_factory=list)
    inside: float = float("nan")  # fraction of the measured cycles' features inside the 90 % predictive band
    posterior: np.ndarray | None = field(default=None, repr=False)  # (gc, gn) on the model's grid
    band: np.ndarray | None = field(default=None, repr=False)  # (3, p) 5/50/95 % of one cycle's features
    measured: np.ndarray | None = field(default=None, repr=False)  # (cycles, p) the session's cycle features
    meta: dict = field(default_factory=dict)  # grid_c (m), grid_n (cycles): the grid's ranges; bins, bands
    # how far the session moved each parameter's marginal from its uniform prior (total variation, 0-1)
    evidence: dict = field(default_factory=dict)

    @property
    def flat(self) -> bool:
        """Whether the session's evidence left both parameters where their prior has them
        (``identify.FLAT``): the estimate is its prior, not a measurement."""
        return bool(self.evidence) and all(v < FLAT for v in self.evidence.values())

    def to_dict(self) -> dict:
        return {**{k: v for k, v in asdict(self).items() if k not in ("posterior", "band", "measured")},
                "flat": self.flat}

    def row(self) -> dict:
        """One table row (SI units): the median and 90 % interval of each parameter with its kind
        (``*_interval``: central, upper bound, lower bound), the verdict."""
        out = {"session": self.session, "cycles": self.cycles, "explains": self.explains, "p_value": self.p_value}
        for name, i in (("clearance_m", self.clearance), ("cycles_run", self.cycles_run), ("wear_depth_m", self.depth)):
            out.update({name: i.median, f"{name}_lo90": i.lo90, f"{name}_hi90": i.hi90, f"{name}_interval": i.kind})
        return out

    def line(self) -> str:
        """The estimate in one line, as the demo's summary and the report's table give it: each median
        and its 90 % interval ("lo-hi", or "at most" / "at least" where one-sided)."""
        if not self.explains:
            return NO_VALUE
        if self.flat:
            return PRIOR_ONLY
        c, n, d = self.clearance, self.cycles_run, self.depth
        return (f"{c.median * 1e3:.3f} mm [{c.text(fmt_mm)}], {n.median / 1e3:.0f}k cycles [{n.text(fmt_kcycles)}], "
                f"wear {d.median * 1e6:.1f} um [{d.text(fmt_um)}]")


def predictive_band(model: EstimatorModel, posterior: np.ndarray, *, draws: int = 4000, seed: int = 0
                    ) -> np.ndarray:
    """The posterior predictive 5 %, 50 % and 95 % of one cycle's features (3, p): parameter values
    drawn from ``posterior`` (on the model's grid), then a cycle of a bench drawn from the tolerances
    at that value (between-bench, cycle-to-cycle, sensor path and emulator error), by sampling with a
    fixed seed (a session gets the same band every time)."""
    rng = np.random.default_rng(seed)
    w = posterior.ravel() / posterior.sum()
    pick = rng.choice(w.size, size=draws, p=w)
    means = model.grid_mean.reshape(w.size, -1)[pick]
    z = rng.standard_normal(means.shape)
    if model.spread is None:
        x = means + z @ linalg.cholesky(model.covariance(1.0), lower=True).T
    else:  # the wear spread at each draw's cycles run
        x, column = means.copy(), pick % model.grid_n.size
        for k in np.unique(column):
            at = column == k
            x[at] += z[at] @ linalg.cholesky(model.covariance(1.0) + model.spread.at(model.grid_n[k]), lower=True).T
    return np.percentile(x, [5.0, 50.0, 95.0], axis=0)


def estimate_features(features: CycleFeatures, model: EstimatorModel, *, label: str = "session") -> Estimate:
    """Posterior of clearance and wear for a session's cycle ``features``."""
    x = features.values
    n = features.cycles
    if n < 1:
        raise ValueError(f"estimate {label}: the session holds no complete crank cycle")
    xbar = x.mean(axis=0)
    logp, d2 = model.log_posterior(xbar, n)
    post = np.exp(logp)
    gc, gn = model.grid_c, model.grid_n
    c_int = Interval.from_weights(gc, post.sum(axis=1), edges=True)
    n_int = Interval.from_weights(gn, post.sum(axis=0), edges=True)
    depth_int = Interval.from_weights(*model.depth_values(post), edges=True)
    i, j = np.unravel_index(int(np.argmax(post)), post.shape)
    cc, nn = np.meshgrid(gc, gn, indexing="ij")
    mc, mn = float((post * cc).sum()), float((post * nn).sum())
    cov = float((post * (cc - mc) * (nn - mn)).sum())
    sd = np.sqrt(float((post * (cc - mc) ** 2).sum()) * float((post * (nn - mn) ** 2).sum()))
    p = float(stats.gamma.sf(float(d2.min()), model.null[0], scale=model.null[1]))
    explains = p >= model.options.consistency
    notes = []
    verdict = (f"clearance {c_int.median * 1e3:.3f} mm (90 % {c_int.text(fmt_mm)}), "
               f"{n_int.median / 1e3:.0f}k cycles run (90 % {n_int.text(fmt_kcycles)})")
    if not explains:
        verdict = NO_VALUE
        notes.append(f"no clearance in {gc[0] * 1e3:.3g}-{gc[-1] * 1e3:.3g} mm and wear of 0-{gn[-1]:,.0f} cycles "
                     f"explains the session (p {p:.2g}): outside the estimator's range, or a sensor path or bench "
                     "unlike the model's")
    evidence = {"clearance": prior_distance(post.sum(axis=1)), "cycles_run": prior_distance(post.sum(axis=0))}
    unmoved = [k for k, v in evidence.items() if v < FLAT]
    if explains and len(unmoved) == 2:
        verdict = PRIOR_ONLY
        notes.append(f"the session's evidence hardly moves the posterior from the uniform prior over clearances "
                     f"{gc[0] * 1e3:.3g}-{gc[-1] * 1e3:.3g} mm and 0-{gn[-1]:,.0f} cycles run (total variation "
                     f"{evidence['clearance']:.2f} and {evidence['cycles_run']:.2f}): the intervals are the prior's, "
                     "not a measurement; the features do not see clearance or wear at this speed and sensor chain")
    elif explains and unmoved:
        what = "the clearance" if unmoved == ["clearance"] else "the cycles run"
        notes.append(f"the session's evidence hardly moves {what} from its uniform prior (total variation "
                     f"{evidence[unmoved[0]]:.2f}): its interval is the prior's, not a measurement")
    edge = post[0].sum() + post[-1].sum() + post[:, -1].sum()
    if explains and edge > 0.2:
        notes.append("much of the posterior lies at the edge of the estimator's range: the truth may lie beyond it")
    one_sided = [f"{name} {i.text(fmt)}" for name, i, fmt in (("clearance", c_int, lambda v: f"{fmt_mm(v)} mm"),
                                                              ("cycles run", n_int, fmt_kcycles),
                                                              ("wear depth", depth_int, lambda v: f"{fmt_um(v)} um"))
                 if i.kind != "central"]
    if explains and verdict != PRIOR_ONLY and one_sided:
        notes.append("one-sided 90 % interval" + ("s" if len(one_sided) > 1 else "") + " where the posterior piles at "
                     "the edge of the estimator's range: " + ", ".join(one_sided))
    if explains and verdict != PRIOR_ONLY and model.spread is None:
        notes.append("the estimator holds one wear run per design clearance: how far another bench's wear "
                     "realisation lies from it is not in the intervals of cycles run and wear depth (build it with "
                     "'wearbench estimator --wear-runs 3')")
    if n < SHORT_SESSION:
        notes.append(f"only {n} complete crank cycle{'s' if n > 1 else ''}: the estimator's statistics hold for "
                     f"sessions of {SHORT_SESSION} or more; record longer for intervals to trust")
    clipped = int(features.clipped.sum())
    if clipped:
        notes.append(f"{clipped} samples at the sensor's range (clipped): impact energies are underestimated")
    sensor = model.sensor.source if model.sensor else "none"
    band = predictive_band(model, post)
    inside = float(np.mean((x >= band[0]) & (x <= band[2])))
    spec = features.spec
    return Estimate(label, n, c_int, n_int, depth_int, (float(gc[i]), float(gn[j])),
                    cov / sd if sd > 0 else 0.0, p, explains, verdict, sensor, notes, inside, post, band, x,
                    {"grid_c": [float(gc[0]), float(gc[-1])], "grid_n": [float(gn[0]), float(gn[-1])],
                     "bins": spec.bins, "bands": [list(b) for b in spec.bands], "estimator": model.estimator.key},
                    evidence)
