"""Measure a bench, not only name it: the workflows behind ``wearbench estimate``, ``track`` and
``calibrate`` on recorded sessions (load them, build or load the estimator or the ensembles on the
compute layer, use the bench's sensor-path calibration, and call ``estimate.py``, ``track.py``,
``calibration.py``). Imports the validation modules; the model only through the estimator and
the ensembles.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path

from wearbench.bench.schema import WearState
from wearbench.validation.inference.calibration import (
    Calibration,
    calibration_key,
    fit_calibration,
    sensor_record,
    session_calibration,
)
from wearbench.validation.inference.ensemble import Ensemble, EnsembleSettings, build_ensembles
from wearbench.validation.inference.estimate import (
    Estimate,
    Estimator,
    EstimatorDesign,
    EstimatorModel,
    build_estimator,
    estimate_features,
    fit_estimator,
)
from wearbench.validation.inference.identify import IdentifyOptions, fit_states
from wearbench.validation.inference.move import Move, stored_move
from wearbench.validation.inference.track import Track, track_features
from wearbench.validation.measurement.session import MeasuredSession, load_session
from wearbench.validation.workflows.assess import Assessment, candidate_states

__all__ = ["calibrate_sessions", "estimate_assessed", "estimate_sessions", "named_outside", "recorded_cycles_run",
           "track_sessions"]


def _grouped(sessions: Sequence[str | Path | MeasuredSession], needs_bench: str | None
             ) -> tuple[list[MeasuredSession], list[list[int]]]:
    """The sessions loaded, and their indices grouped by (bench file, commanded speed); a session
    without a recorded bench file is an error saying what needs it (``needs_bench``; None: allowed)."""
    loaded = [s if isinstance(s, MeasuredSession) else load_session(s) for s in sessions]
    groups: dict[tuple, list[int]] = {}
    for i, s in enumerate(loaded):
        if s.bench is None and needs_bench is not None:
            raise ValueError(f"session {s.label}: no bench file recorded in it; {needs_bench}")
        groups.setdefault((s.bench.sha256 if s.bench else "", round(s.commanded_speed, 6)), []).append(i)
    return loaded, list(groups.values())


def _one_bench(loaded: Sequence[MeasuredSession], noun: str, verb: str, *, sensor: bool = False) -> MeasuredSession:
    """The first of ``loaded``, which all record one bench file (and, with ``sensor``, one sensor
    calibration); else one ValueError naming the session that does not."""
    first = loaded[0]
    if first.bench is None:
        raise ValueError(f"session {first.label}: no bench file recorded in it; {noun} needs one")
    for s in loaded[1:]:
        if s.bench is None or s.bench.sha256 != first.bench.sha256 or (
                sensor and sensor_record(s.metadata) != sensor_record(first.metadata)):
            what = "bench file or sensor" if sensor else "bench file"
            raise ValueError(f"session {s.label}: another {what} than {first.label}; {verb} one "
                             f"{'bench and sensor' if sensor else 'bench'} at a time")
    return first


def calibrate_sessions(sessions: Sequence[str | Path | MeasuredSession], state: str, *,
                       candidates: str | Path | Sequence[WearState] | None = None,
                       settings: EnsembleSettings | None = None, options: IdentifyOptions | None = None,
                       ensembles: Mapping[str, Ensemble] | None = None, mount: str = "",
                       scheduler: str | None = None, workers: int | None = None,
                       progress: str | None = "theory ensembles",
                       before: Callable[[str], object] | None = None) -> Calibration:
    """The sensor-path calibration of one bench from ``sessions`` recorded in the known ``state``
    (a ``[[state]]`` name of the bench or of ``candidates``); see ``calibration.py``. Not saved.
    ``before`` is called with the calibration's key once the sessions are read, before any ensemble
    is built (``wearbench calibrate`` refuses an existing calibration there, not minutes later)."""
    settings, options = settings or EnsembleSettings(), options or IdentifyOptions()
    loaded = [s if isinstance(s, MeasuredSession) else load_session(s) for s in sessions]
    first = _one_bench(loaded, "calibration", "calibrate", sensor=True)
    if before is not None:
        spec = next(iter(ensembles.values())).settings.features if ensembles else settings.features
        before(calibration_key(first.bench, first.metadata, spec, mount))
    ens = ensembles or build_ensembles(first.bench, candidate_states(first.bench, candidates), speed=first.commanded_speed,
                                       settings=settings, scheduler=scheduler, workers=workers, progress=progress)
    if state not in ens:
        raise ValueError(f"calibrate: --state {state!r}: expected one of the bench's states {list(ens)}")
    spec = next(iter(ens.values())).settings.features
    exact = fit_states(ens, replace(options, sensor_path="none"))
    key = calibration_key(first.bench, first.metadata, spec, mount)
    return fit_calibration([s.features(spec) for s in loaded], exact, state, key=key,
                           bench=first.bench.name, labels=[s.label for s in loaded], mount=mount)


def estimate_sessions(sessions: Sequence[str | Path | MeasuredSession], *, design: EstimatorDesign | None = None,
                      estimator: Estimator | None = None, options: IdentifyOptions | None = None,
                      calibration: str | Path | None = "auto", mount: str = "", scheduler: str | None = None,
                      workers: int | None = None, progress: str | None = "estimator") -> list[Estimate]:
    """Clearance and wear of each session (paths or ``MeasuredSession``) with credible intervals.

    The estimator of each (bench, commanded speed) is built once on the compute layer (or the
    shipped one used when its key matches; ``estimator`` uses that one); ``design`` defaults to
    ``EstimatorDesign()``. ``calibration``/``mount``: as ``assess.assess_sessions``.
    """
    design, options = design or EstimatorDesign(), options or IdentifyOptions()
    loaded, groups = _grouped(sessions, "the estimator needs one" if estimator is None else None)
    out: list[Estimate | None] = [None] * len(loaded)
    for idx in groups:
        first = loaded[idx[0]]
        est = estimator or build_estimator(first.bench, design, speed=first.commanded_speed, scheduler=scheduler,
                                           workers=workers, progress=progress)
        fitted: dict[str, EstimatorModel] = {}
        for i in idx:
            s = loaded[i]
            cal = session_calibration(s, est.spec, calibration, mount)
            tag = cal.key if cal else ""
            if tag not in fitted:
                fitted[tag] = fit_estimator(est, options, sensor=cal.path if cal else None)
            out[i] = estimate_features(s.features(est.spec), fitted[tag], label=s.label)
            if cal is not None:
                out[i].notes.append(f"sensor path: {cal.describe()}")
    return out


def estimate_assessed(assessed: Sequence[Assessment], estimator: Estimator | EstimatorDesign, *,
                      options: IdentifyOptions | None = None, calibration: str | Path | None = "auto",
                      mount: str = "", scheduler: str | None = None, workers: int | None = None,
                      progress: str | None = "estimator") -> list[Assessment]:
    """Each assessed session's clearance and wear beside its identification (``Assessment.estimate``,
    shown in the report): with ``estimator``, or the one of that design (as :func:`estimate_sessions`);
    ``calibration``/``mount``: as the identification used them. Returns ``assessed``."""
    given = estimator if isinstance(estimator, Estimator) else None
    design = estimator if isinstance(estimator, EstimatorDesign) else None
    found = estimate_sessions([a.session for a in assessed], design=design, estimator=given, options=options,
                              calibration=calibration, mount=mount, scheduler=scheduler, workers=workers,
                              progress=progress)
    for a, e in zip(assessed, found, strict=True):
        a.estimate = e
        note = named_outside(a, e)
        if note:
            a.identification.notes.append(note)
    return list(assessed)


def named_outside(a: Assessment, est: Estimate | None) -> str | None:
    """A note when the identified state's clearance lies outside the estimate's 90 % interval: the bench
    is between the candidates (the nearest one named) or not among them."""
    named = next((s for s in a.session.bench.states if s.name == a.identification.verdict), None) \
        if a.session.bench is not None else None
    if est is None or not est.explains or named is None or not named.clearances:
        return None
    c = est.clearance
    outside = [v for v in named.clearances.values() if not c.contains(v)]
    if not outside:
        return None
    return (f"the estimate puts the clearance at {c.median * 1e3:.3f} mm [{c.lo90 * 1e3:.3f}-{c.hi90 * 1e3:.3f}], "
            f"outside {named.name}'s {outside[0] * 1e3:.3f} mm: the bench lies between the candidates or beyond them")


def recorded_cycles_run(session: MeasuredSession) -> float | None:
    """The cycles the bench had run before ``session`` as recorded (``wearbench record --cycles-run``)."""
    text = session.metadata.get("session", {}).get("cycles_run")
    try:
        return None if text is None else float(text)
    except ValueError:
        raise ValueError(f"session {session.label}: metadata session.cycles_run = {text!r}: expected a number of "
                         "cycles") from None


def _cycles_run(loaded: Sequence[MeasuredSession], given: Sequence[float] | None) -> tuple[list[float], list[str]]:
    """Cycles run per session: ``given`` (one per session), else as recorded; notes where they differ."""
    recorded = [recorded_cycles_run(s) for s in loaded]
    if given is None:
        missing = [s.label for s, n in zip(loaded, recorded, strict=True) if n is None]
        if missing:
            raise ValueError(f"session {missing[0]}: no cycles run recorded in it (wearbench record --cycles-run); "
                             "give them to track (--cycles-run N1,N2,... in the sessions' order)")
        return [float(n) for n in recorded], []
    if len(given) != len(loaded):
        raise ValueError(f"cycles run: {len(given)} values for {len(loaded)} sessions; expected one per session")
    notes = [f"{s.label}: cycles run {g:,.0f} as given, {n:,.0f} as recorded in the session"
             for s, g, n in zip(loaded, given, recorded, strict=True) if n is not None and n != g]
    return [float(g) for g in given], notes


def track_sessions(sessions: Sequence[str | Path | MeasuredSession], cycles_run: Sequence[float] | None = None, *,
                   limit: float | None = None, design: EstimatorDesign | None = None,
                   estimator: Estimator | None = None, options: IdentifyOptions | None = None,
                   calibration: str | Path | None = "auto", mount: str = "", move: Move | bool = True,
                   scheduler: str | None = None, workers: int | None = None,
                   progress: str | None = "estimator") -> Track:
    """Wear over one bench's life from ``sessions`` recorded after ``cycles_run`` cycles (see
    ``track.py``; None: as each session records it, ``wearbench record --cycles-run``); ``limit``: a
    clearance limit (m); ``move``: True uses the measured move stored with the estimator when it has
    one (``track_move.stored_move``; one keyed to another estimator is an error), False none, or this
    one (checked against the estimator's key). Other arguments as :func:`estimate_sessions`."""
    design, options = design or EstimatorDesign(), options or IdentifyOptions()
    loaded = [s if isinstance(s, MeasuredSession) else load_session(s) for s in sessions]
    first = _one_bench(loaded, "tracking", "track")
    cycles_run, differ = _cycles_run(loaded, cycles_run)
    est = estimator or build_estimator(first.bench, design, speed=first.commanded_speed, scheduler=scheduler,
                                       workers=workers, progress=progress)
    cal = session_calibration(first, est.spec, calibration, mount)
    model = fit_estimator(est, options, sensor=cal.path if cal else None)
    if isinstance(move, Move) and move.estimator != est.key:
        raise ValueError(f"move {move.path or '(given)'}: field 'estimator' = {move.estimator!r}: measured against "
                         f"another estimator; expected {est.key!r}")
    used = move if isinstance(move, Move) else stored_move(est) if move else None
    track = track_features([s.features(est.spec) for s in loaded], cycles_run, model,
                           coefficient=first.bench.wear.coefficient, limit=limit, labels=[s.label for s in loaded],
                           move=used)
    if cal is not None:
        track.notes.append(f"sensor path: {cal.describe()}")
    track.notes.extend(differ)
    return track
