"""Simulated truths and lives of known truth through the emulator's sensor chain, for the estimator:
what ``benchmarks/validation/estimate.py`` scores it on, and what ``wearbench estimator --lives`` measures the
benches' move from new to worn on (``validation/track_move.py``).

A truth is the bench drawn from the bench file's ``[tolerances]`` with its own seed (the estimator's
design uses seeds 1..M), worn from a clearance, run from a random start, and seen through the
emulator's sensor chain (the bench file's ``[emulator.accelerometer]``; ``spread``: True, a mount or
carriage mode drawn per truth, ``SensorSpread`` without its cross-axis part (what the cached lives
and the shipped move hold); ``"cross-axis"``, the whole of ``SensorSpread``'s draw, the cross-axis
sensitivity to the carriage's lateral mode driven by the lateral force of the same run included)
applied in-process to the model's acceleration. A
life is one such bench worn with a factor times the file's wear coefficient and recorded after 0 and
every stage. The top layer: imports the model, the emulators and the validation layer.
"""

from __future__ import annotations

import tempfile
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

import numpy as np
from wearbench.bench.schema import Bench, WearState
from wearbench.compute.options import DEFAULT, Compute
from wearbench.validation.estimation.estimate import Estimator, EstimatorDesign
from wearbench.validation.measurement.features import FeatureSpec

__all__ = ["life_cost", "life_features", "life_means", "life_plan", "life_revolutions", "measure_move", "move_with_rate",
           "state_session", "surfaces_wear", "truth_features"]


def _sensor_chain(bench: Bench, spread: bool | str, seed: int):
    """A truth's emulated sensor chain (``spread``: see :func:`truth_features`), made and checked before
    anything is simulated."""
    from wearbench.hardware.emulators.carriage import carriage
    from wearbench.hardware.emulators.config import EmulatorConfig, SensorSpread
    from wearbench.hardware.emulators.sensor import SensorChain

    if spread not in (False, True, "cross-axis"):
        raise ValueError(f"truth_features: spread = {spread!r}: expected False, True or 'cross-axis'")
    acc = EmulatorConfig.from_bench(bench).accelerometer
    if spread:
        acc = (SensorSpread() if spread == "cross-axis" else SensorSpread(cross_axis=(0.0, 0.0))).draw(acc, seed)
    sensor = bench.sensor("accelerometer")
    chain = SensorChain(acc, sensor.sample_rate, sensor.range, np.random.default_rng([seed, 7]))
    if chain.lateral and carriage(bench) is None:
        raise ValueError(f"truth_features: {bench.name}: cross-axis needs the accelerometer's carriage on a guide "
                         "held by ideal pins (hardware/emulators/carriage.py); this bench has none")
    return chain


def surfaces_wear(files: Mapping[str, str | Path]) -> tuple[float, float]:
    """Cycles run and wear depth (m: the largest bearing plus journal depth of any joint, what the
    estimator calls the depth) of worn-surface files ``{joint: path}``; (0, 0) for none."""
    from wearbench.model.surfaces import JointSurfaces

    worn = [JointSurfaces.load(f) for f in files.values()]
    return max((w.cycles for w in worn), default=0.0), max((sum(w.max_depth) for w in worn), default=0.0)


def state_session(bench: Bench, state: WearState, seed: int, cycles: int, spread: bool | str, *,
                  label: str | None = None):
    """A compute task: one session of :func:`truth_features` of ``bench`` drawn with ``seed`` in the
    worn ``state``, on the state's own surface files (keyed by their content)."""
    from wearbench.bench.content import bench_key, file_digest
    from wearbench.compute import Task, task_key

    clearance = max(state.clearances.values() or [j.clearance.radial_clearance for j in bench.clearance_joints])
    return Task(truth_features, {"bench": bench, "clearance": clearance, "cycles_run": 0.0, "seed": seed,
                                 "cycles": cycles, "spread": spread, "files": dict(state.surfaces)},
                task_key("state-session", bench_key(bench), state.name, clearance,
                         {j: file_digest(f) for j, f in state.surfaces.items()}, seed, cycles, spread),
                label or f"{state.name} {seed}")


def truth_features(bench: Bench, clearance: float, cycles_run: float, seed: int, cycles: int,
                   spread: bool | str, files: dict | None = None, spec: FeatureSpec | None = None, *,
                   wear: str = "nominal") -> dict:
    """One truth's cycle features through the sensor chain (a compute-layer task); ``spread``: False
    (the file's path), True (a drawn axial path) or "cross-axis" (a drawn path with cross-axis);
    ``files``: worn surfaces to use instead of a wear run of ``cycles_run``; ``spec``: the features
    (default the bench's own at its speed, ``measurement.scaling``; an estimator's ``spec``);
    ``wear``: who wears through ``cycles_run`` in one stage, "nominal" (the bench file's bench) or
    "drawn" (the truth's own bench, drawn with ``seed``, at its true speed from its random start:
    ``estimate.wear_trajectory``)."""
    from wearbench.hardware.emulators.carriage import lateral_force
    from wearbench.model.realisation import simulate_state
    from wearbench.model.surfaces import JointSurfaces
    from wearbench.validation.estimation.estimate import wear_trajectory
    from wearbench.validation.measurement.features import cycle_features
    from wearbench.validation.measurement.scaling import resolve_analysis

    if wear not in ("nominal", "drawn"):
        raise ValueError(f"truth_features: wear = {wear!r}: expected 'nominal' or 'drawn'")
    spec = spec or resolve_analysis(bench).features
    chain = _sensor_chain(bench, spread, seed)
    joints = [j.name for j in bench.clearance_joints]
    files = dict(files or {})
    _, depth = surfaces_wear(files)
    with tempfile.TemporaryDirectory() as tmp:
        if cycles_run > 0:
            worn = wear_trajectory(bench, clearance, 1, cycles_run, bench.speed, seed if wear == "drawn" else None)
            for j, (b, jr, cyc) in worn[-1].items():
                s = JointSurfaces(b, jr, cyc, f"truth {seed}")
                files[j] = s.save(Path(tmp) / f"{j}.npz")
                depth = max(depth, sum(s.max_depth))
        state = WearState("truth", dict.fromkeys(joints, clearance), files)
        run = simulate_state(bench, state, seed, revolutions=cycles + 1.0, settle=2.0,
                             output_rate=chain.internal_rate)
    m = chain.oversample
    samples = chain.process(run.acc, lateral_force(run.realisation.bench, run.table) if chain.lateral else None)
    t, crank = run.t[m - 1::m], run.crank[m - 1::m]
    f = cycle_features(t, crank, samples.astype(float), spec)  # only its values are kept
    return {"features": f.values[:cycles], "depth": depth, "mode": chain.acc.resonance,
            "cross_axis": chain.acc.cross_axis}


def life_features(bench: Bench, clearance: float, factor: float, step: float, stages: int, seed: int, cycles: int,
                  spread: bool | str, spec: FeatureSpec | None = None) -> dict:
    """One simulated life (a compute-layer task): the bench worn from ``clearance`` with ``factor`` x
    the file's wear coefficient through ``stages`` stages of ``step`` cycles; a session of ``cycles``
    through the sensor chain at 0 and after every stage but the last; the truth's depth after each
    (features of ``spec``, as :func:`truth_features`)."""
    from wearbench.model.wear_stages import StagePlan, run_stages

    _sensor_chain(bench, spread, seed)  # a bad spread or sensor path fails before the wear stages
    joints = [j.name for j in bench.clearance_joints]
    plan = StagePlan.from_bench(bench, stages=stages, stage_cycles=step)
    run = run_stages(bench, replace(plan, coefficient=bench.wear.coefficient * factor),
                     clearances=dict.fromkeys(joints, clearance))
    depth = [0.0] + [max(sum(s.max_depth) for s in st.surfaces.values()) for st in run.stages]
    feats = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(stages):  # sessions at 0 and after stages 1 .. stages-1
            files = {j: s.save(Path(tmp) / f"{j}_{k}.npz") for j, s in run.stages[k - 1].surfaces.items()} if k else {}
            feats.append(truth_features(bench, clearance, 0.0, seed, cycles, spread, files=files, spec=spec)["features"])
    return {"features": feats, "depth": depth}


def life_revolutions(cycles: int, stages: int = 5) -> float:
    """Motor revolutions one life of :func:`life_features` simulates, about: its wear run
    (``estimate.wear_revolutions``) and a session of ``cycles`` (and its settling) at 0 and after every
    stage but the last."""
    from wearbench.validation.estimation.estimate import wear_revolutions

    return wear_revolutions(stages) + stages * (cycles + 1.0 + 2.0)


def life_cost(bench: Bench, design: EstimatorDesign, speed: float):
    """What a life's revolutions cost (``compute.cost.Cost``): the bench at the middle of the design's
    clearances at commanded ``speed``, on the emulated sensor chain's internal rate."""
    from wearbench.compute.cost import Cost

    c = design.clearances[len(design.clearances) // 2]
    state = WearState("life", {j.name: c for j in bench.clearance_joints})
    return Cost(bench, state, speed, _sensor_chain(bench, False, 1).internal_rate, "lives")


def life_plan(est: Estimator, lives: int, factor: float, seed: int) -> tuple[float, list[tuple[float, int]]]:
    """The cycles between a life's sessions (a sixth of the design's last cycles run, so the last of
    its five sessions at ``factor`` <= 1.5 lies inside the design) and each life's (initial clearance,
    seed): clearances uniform over the design's range less its lowest eighth and highest quarter (the
    test bed's 0.30-0.55 mm of 0.25-0.65 mm, where a life's wear stays inside the design), seeds
    ``seed`` + k (the design's benches are seeds 1..M)."""
    lo, hi = est.design.clearances[0], est.design.clearances[-1]
    step = est.design.cycles[-1] / 6
    if not 0 < factor <= 1.5:
        raise ValueError(f"lives: wear factor {factor}: expected within (0, 1.5] (the last session, 4 x "
                         f"{step:,.0f} cycles x the factor, must lie inside the design's {est.design.cycles[-1]:,.0f})")
    if seed <= est.design.settings.realisations:
        raise ValueError(f"lives: seed {seed}: expected above the design's seeds 1..{est.design.settings.realisations}")
    rng = np.random.default_rng(seed)
    span = hi - lo
    return step, [(float(rng.uniform(lo + span / 8, hi - span / 4)), seed + k) for k in range(lives)]


def life_means(result: dict) -> np.ndarray:
    """(S, p): the mean cycle features of each session of one :func:`life_features` result."""
    return np.stack([np.asarray(f).mean(axis=0) for f in result["features"]])


def move_with_rate(model, lives, about: dict, *, cycles: int, benches=None):
    """The move from new to worn measured on ``lives`` (``track_move.life_move``: (session means,
    cycles run, clearance, factor) each) with the features' rate along the same lives against
    clearance (``track.life_rate``; sessions of ``cycles`` cycles)."""
    from wearbench.validation.estimation.move import life_move
    from wearbench.validation.estimation.track import life_rate

    move = life_move(model, lives, about, benches=benches)
    return replace(move, rate=life_rate(model, lives, move, cycles=cycles))


def measure_move(bench: Bench, est: Estimator, *, lives: int = 20, factor: float = 1.3, spread: bool = False,
                 cycles: int = 20, seed: int = 100_000, compute: Compute = DEFAULT):
    """The benches' move from new to worn beyond ``est``'s mean change (``track_move.Move``), with the
    features' rate along the lives against clearance (``track.life_rate``), measured
    on ``lives`` simulated lives of ``bench`` (:func:`life_plan`; ``spread``: each with a drawn sensor
    path) run on the compute layer and cached by content (the estimator's key, the bench, its
    emulated sensor chain, the life). A failed life raises (a move measured on fewer lives than asked
    would say otherwise)."""
    from wearbench.bench.content import bench_key, canonical
    from wearbench.compute import Task, TaskFailure, task_key
    from wearbench.hardware.emulators.config import EmulatorConfig
    from wearbench.validation.estimation.estimate import fit_estimator

    if lives < 3:
        raise ValueError(f"lives = {lives}: expected at least 3 (the move's mean and its error need three independent "
                         "benches; 20 or more)")
    step, plan = life_plan(est, lives, factor, seed)
    chain = canonical(EmulatorConfig.from_bench(bench).accelerometer)
    tasks = [Task(life_features, {"bench": bench, "clearance": c, "factor": factor, "step": step, "stages": 5,
                                  "seed": s, "cycles": cycles, "spread": spread, "spec": est.spec},
                  task_key("estimator-life", est.key, bench_key(bench), chain, c, factor, step, s, cycles, spread),
                  f"life {s}", life_revolutions(cycles)) for c, s in plan]
    runs = compute.run(tasks, label="lives", cost=life_cost(bench, est.design, est.speed))
    failed = [r for r in runs if isinstance(r, TaskFailure)]
    if failed:
        raise RuntimeError(f"{len(failed)} of {lives} simulated lives failed; the first: {failed[0]}")
    sessions = [k * step for k in range(5)]
    model = fit_estimator(est)
    about = {"bench": bench.name, "sensor_paths": ["drawn mounts" if spread else "default path"],
             "seeds": [s for _, s in plan], "clearances": [c for c, _ in plan], "factor": factor,
             "sessions": sessions, "cycles": cycles}
    return move_with_rate(model, [(life_means(r), sessions, c, factor) for r, (c, _) in zip(runs, plan, strict=True)],
                          about, cycles=cycles)
