"""Measure a bench, not only name it: the workflows behind ``wearbench estimate``, ``track`` and
``calibrate`` on recorded sessions (a :class:`~wearbench.validation.workflows.session_set.SessionSet`
loads and groups them and finds their theory; ``inference`` estimates, tracks and calibrates).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path

from wearbench.bench.content import bench_key
from wearbench.bench.schema import WearState
from wearbench.compute.options import Compute
from wearbench.validation.estimation.estimate import (
    DesignRequest,
    Estimate,
    Estimator,
    EstimatorDesign,
    EstimatorModel,
    estimate_features,
    fit_estimator,
    fmt_mm,
)
from wearbench.validation.estimation.move import Move, stored_move
from wearbench.validation.estimation.track import Track, track_features
from wearbench.validation.inference.calibration import Calibration, calibration_key, fit_calibration
from wearbench.validation.inference.ensemble import (
    Ensemble,
    EnsembleSettings,
    EnsembleSize,
    resolve_settings,
)
from wearbench.validation.inference.identify import IdentifyOptions, fit_states, identify_features
from wearbench.validation.measurement.scaling import resolve_analysis
from wearbench.validation.measurement.session import MeasuredSession
from wearbench.validation.workflows.assess import Assessment
from wearbench.validation.workflows.session_set import SessionSet, candidate_states

Sessions = SessionSet | Sequence[str | Path | MeasuredSession]
EstimatorGiven = Estimator | str | Path | None

__all__ = [
    "calibrate_sessions",
    "check_life_order",
    "estimate_assessed",
    "estimate_sessions",
    "named_outside",
    "recorded_cycles_run",
    "track_sessions",
]


def calibrate_sessions(sessions: Sessions, state: str, *,
                       candidates: str | Path | Sequence[WearState] | None = None,
                       settings: EnsembleSettings | EnsembleSize | None = None, options: IdentifyOptions | None = None,
                       ensembles: Mapping[str, Ensemble] | str | Path | None = None, mount: str = "",
                       compute: Compute | None = None, before: Callable[[str], object] | None = None,
                       force: bool = False) -> Calibration:
    """The sensor-path calibration of one bench from ``sessions`` recorded in the known ``state``
    (a ``[[state]]`` name of the bench or of ``candidates``); see ``calibration.py``. Not saved.
    ``before`` is called with the calibration's key once the sessions are read, before any ensemble
    is built (``wearbench calibrate`` refuses an existing calibration there, not minutes later).

    A calibration the sessions doubt is refused (ValueError naming why) unless ``force``: the sessions
    stay far from ``state`` with the fitted sensor path (p below ``options.consistency``), or a session
    is identified as another candidate state (with the unmeasured mount's prior) at the options'
    threshold. With ``force`` it is returned with its ``doubts``."""
    options = options or IdentifyOptions()
    sessions = SessionSet.of(sessions, calibration=None, mount=mount)
    group = sessions.one_bench("calibration", sensor=True)
    sessions.refuse_duplicates("calibration")
    first = group.first
    ready = sessions.ensembles(group, candidates=candidates, ensembles=ensembles) if ensembles is not None else None
    names = list(ready) if ready else [s.name for s in candidate_states(first.bench, candidates)]
    if state not in names:
        raise ValueError(f"calibrate: --state {state!r}: expected one of the bench's states {names}")
    if ready is None:  # resolved for the bench and speed (and checked) before any work
        settings = resolve_settings(settings, first.bench, group.speed)
    spec = next(iter(ready.values())).settings.features if ready else settings.features
    if before is not None:
        before(calibration_key(first.bench, first.metadata, spec, mount))
    ens = ready or sessions.ensembles(group, candidates=candidates, settings=settings, compute=compute)
    spec = next(iter(ens.values())).settings.features
    features = [sessions.features(s, spec) for s in sessions]
    exact = fit_states(ens, replace(options, sensor_path="none"))
    cal = fit_calibration(features, exact, state, key=calibration_key(first.bench, first.metadata, spec, mount),
                          bench=first.bench.name, bench_key=bench_key(first.bench), labels=sessions.labels, mount=mount)
    doubts = []
    if cal.p_value < options.consistency:
        doubts.append(f"with the fitted sensor path the sessions are still far from {state!r} (p {cal.p_value:.2g})")
    models = fit_states(ens, options)
    for s, f in zip(sessions, features, strict=True):
        found = identify_features(f, models, label=s.label)
        if found.verdict in ens and found.verdict != state:
            doubts.append(f"session {s.label} is identified as {found.verdict!r} (p {found.posterior[found.verdict]:.3f}), "
                          f"{state!r} p {found.posterior[state]:.3f}")
    if doubts and not force:
        raise ValueError(f"calibrate: {'; '.join(doubts)}: is the bench really in {state!r}? (a mount mode inside an "
                         "impact band or a bench at the edge of its tolerances can do this too: --force stores the "
                         "calibration anyway)")
    return replace(cal, doubts=tuple(doubts))


def estimate_sessions(sessions: Sessions, *, design: EstimatorDesign | DesignRequest | None = None,
                      estimator: EstimatorGiven = None,
                      options: IdentifyOptions | None = None, calibration: str | Path | None = "auto",
                      mount: str = "", compute: Compute | None = None) -> list[Estimate]:
    """Clearance and wear of each session (paths, ``MeasuredSession``s or a ``SessionSet``) with
    credible intervals.

    The estimator of each (bench, commanded speed) is ``estimator`` (an ``Estimator`` or its file,
    refused before any work where it was built for another bench or speed), else ``design``'s (a
    ``DesignRequest`` or None: the bench's own, ``EstimatorDesign.for_bench``, every group's checked
    before any is built): the shipped one when its key matches, built on the compute layer otherwise.
    ``calibration``/``mount``: as :func:`~wearbench.validation.workflows.assess.assess_sessions`.
    """
    options = options or IdentifyOptions()
    sessions = SessionSet.of(sessions, calibration=calibration, mount=mount)
    if estimator is None:
        sessions.require_benches("the estimator needs its bench")
    elif not isinstance(estimator, Estimator):
        from wearbench.validation.estimation.estimate import load_estimator

        estimator = load_estimator(estimator)
    sessions.check_artefacts(estimator=estimator, design=design, theory=("estimator",))
    out: list[Estimate | None] = [None] * len(sessions)
    for group in sessions.groups():
        est = sessions.estimator(group, design=design, estimator=estimator, compute=compute)
        fitted: dict[str, EstimatorModel] = {}
        for i, s in zip(group.indices, group.sessions, strict=True):
            cal = sessions.calibration(s, est.spec)
            tag = cal.key if cal else ""
            if tag not in fitted:
                fitted[tag] = fit_estimator(est, options, sensor=cal.path if cal else None)
            feats = sessions.features(s, est.spec)
            out[i] = estimate_features(feats, fitted[tag], label=s.label)
            if cal is not None:
                out[i].notes.append(f"sensor path: {cal.describe()}")
            analysis = resolve_analysis(group.bench, group.speed)
            for note in (analysis.speed_note(), s.resolution_note(feats)):
                if note:
                    out[i].notes.append(note)
    return out


def estimate_assessed(assessed: Sequence[Assessment], estimator: Estimator | EstimatorDesign | DesignRequest | None,
                      *, options: IdentifyOptions | None = None, calibration: str | Path | None = "auto",
                      mount: str = "", compute: Compute | None = None) -> list[Assessment]:
    """Each assessed session's clearance and wear beside its identification (``Assessment.estimate``,
    shown in the report): with ``estimator``, or the one of that design (a design or request, None:
    each bench's own, as :func:`estimate_sessions`); ``calibration``/``mount``: as the identification
    used them. Returns ``assessed``."""
    given = estimator if isinstance(estimator, Estimator) else None
    design = None if given is not None else estimator
    found = estimate_sessions([a.session for a in assessed], design=design, estimator=given, options=options,
                              calibration=calibration, mount=mount, compute=compute)
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
    return (f"the estimate puts the clearance at {c.median * 1e3:.3f} mm [{c.text(fmt_mm)}], "
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


def check_life_order(loaded: Sequence[MeasuredSession], cycles_run: Sequence[float]) -> None:
    """Refuse cycles run that go back in time: a session recorded after another (its recorded start)
    with fewer cycles run than it (a bench does not unwear)."""
    from datetime import datetime

    dated = []
    for s, n in zip(loaded, cycles_run, strict=True):
        text = s.metadata.get("session", {}).get("started_at")
        try:
            dated.append((datetime.fromisoformat(text), n, s.label))
        except (TypeError, ValueError):
            return  # not every session says when it was recorded: nothing to check against
    dated.sort()
    for (t0, n0, a), (t1, n1, b) in itertools.pairwise(dated):
        if n1 < n0:
            raise ValueError(f"session {b}: recorded after {a} ({t1:%Y-%m-%d %H:%M} after {t0:%Y-%m-%d %H:%M}) with "
                             f"fewer cycles run ({n1:,.0f} < {n0:,.0f}); a bench does not unwear: check --cycles-run or "
                             "the sessions' order")


def track_sessions(sessions: Sessions, cycles_run: Sequence[float] | None = None, *,
                   limit: float | None = None, design: EstimatorDesign | DesignRequest | None = None,
                   estimator: EstimatorGiven = None,
                   options: IdentifyOptions | None = None, calibration: str | Path | None = "auto", mount: str = "",
                   move: Move | bool = True, compute: Compute | None = None) -> Track:
    """Wear over one bench's life from ``sessions`` recorded after ``cycles_run`` cycles (see
    ``track.py``; None: as each session records it, ``wearbench record --cycles-run``); ``limit``: a
    clearance limit (m); ``move``: True uses the measured move stored with the estimator when it has
    one (``move.stored_move``; one keyed to another estimator is an error), False none, or this
    one (checked against the estimator's key). Other arguments as :func:`estimate_sessions`."""
    options = options or IdentifyOptions()
    sessions = SessionSet.of(sessions, calibration=calibration, mount=mount)
    group = sessions.one_bench("tracking")
    sessions.refuse_duplicates("tracking")
    cycles_run, differ = _cycles_run(sessions.sessions, cycles_run)
    check_life_order(sessions.sessions, cycles_run)
    if estimator is not None and not isinstance(estimator, Estimator):
        from wearbench.validation.estimation.estimate import load_estimator

        estimator = load_estimator(estimator)
    sessions.check_artefacts(estimator=estimator, design=design, theory=("estimator",))
    est = sessions.estimator(group, design=design, estimator=estimator, compute=compute)
    cal = sessions.calibration(group.first, est.spec)
    model = fit_estimator(est, options, sensor=cal.path if cal else None)
    if isinstance(move, Move) and move.estimator != est.key:
        raise ValueError(f"move {move.path or '(given)'}: field 'estimator' = {move.estimator!r}: measured against "
                         f"another estimator; expected {est.key!r}")
    used = move if isinstance(move, Move) else stored_move(est) if move else None
    track = track_features([sessions.features(s, est.spec) for s in sessions], cycles_run, model,
                           coefficient=group.bench.wear.coefficient, limit=limit, labels=sessions.labels, move=used)
    if cal is not None:
        track.notes.append(f"sensor path: {cal.describe()}")
    track.notes.extend(differ)
    return track
