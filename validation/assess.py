"""Assess recorded sessions against theory ensembles: which state, how well, and the report.

The workflow behind ``wearbench identify``, ``wearbench compare --candidates`` and the demo: load
the sessions, build (or load) one ensemble per candidate state for each bench and commanded speed
on the compute layer, identify each session (``identify.py``), compare its cycles with the band of
the identified state (``bands.py``), score its five-cycle windows against that state's ensemble
median, and write the report when asked. Imports the validation modules; the model only through
the ensembles.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from wearbench.bench.load import load_states
from wearbench.bench.schema import WearState
from wearbench.validation.bands import BandComparison, compare_bands, ensemble_theory
from wearbench.validation.calibration import (
    Calibration,
    calibration_key,
    find_calibration,
    fit_calibration,
    load_calibration,
    sensor_record,
)
from wearbench.validation.compare import (
    CompareOptions,
    SessionComparison,
    compare_session,
    motor_speed,
)
from wearbench.validation.ensemble import Ensemble, EnsembleSettings, build_ensembles
from wearbench.validation.estimate import (
    Estimate,
    Estimator,
    EstimatorDesign,
    EstimatorModel,
    build_estimator,
    estimate_features,
    fit_estimator,
)
from wearbench.validation.features import CycleFeatures, FeatureSpec, cycle_curves, cycle_features
from wearbench.validation.filters import parse_filter
from wearbench.validation.identify import (
    Identification,
    IdentifyOptions,
    fit_states,
    identify_features,
)
from wearbench.validation.measured import MeasuredSession, load_session
from wearbench.validation.track import Track, track_features

__all__ = ["Assessment", "assess_sessions", "calibrate_sessions", "estimate_sessions", "session_calibration", "session_features", "track_sessions"]


@dataclass
class Assessment:
    """One session: its identification, its band against the identified (or top) state, and its
    windows scored against that state's ensemble median."""

    session: MeasuredSession
    identification: Identification
    bands: BandComparison
    comparison: SessionComparison | None  # None when no five-cycle window could be scored


def _arrays(session: MeasuredSession) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Acceleration times and samples with the encoder's crank angle interpolated to each sample."""
    acc = session.acceleration
    t = acc["time"].to_numpy(float)
    enc = session.encoder
    return t, np.interp(t, enc["time"].to_numpy(float), enc["angle"].to_numpy(float)), acc["acc"].to_numpy(float)


def session_features(session: MeasuredSession, spec: FeatureSpec | None = None,
                     arrays: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> CycleFeatures:
    """Cycle features of a measured session; clipped samples counted at the accelerometer's range.
    ``arrays``: the session's ``_arrays`` when the caller has them already."""
    range_ = None
    if session.bench is not None:
        try:
            range_ = session.bench.sensor("accelerometer").range
        except KeyError:
            range_ = None
    return cycle_features(*(arrays or _arrays(session)), spec or FeatureSpec(), range_=range_)


def _grouped(sessions: Sequence[str | Path | MeasuredSession], needs_bench: str | None
             ) -> tuple[list[MeasuredSession], list[list[int]]]:
    """The sessions loaded, and their indices grouped by (bench file, commanded speed); a session
    without a recorded bench file is an error saying what needs it (``needs_bench``; None: allowed)."""
    loaded = [s if isinstance(s, MeasuredSession) else load_session(s) for s in sessions]
    groups: dict[tuple, list[int]] = {}
    for i, s in enumerate(loaded):
        if s.bench is None and needs_bench is not None:
            raise ValueError(f"session {s.label}: no bench file recorded in it; {needs_bench}")
        groups.setdefault((s.bench.sha256 if s.bench else "", round(commanded_speed(s), 6)), []).append(i)
    return loaded, list(groups.values())


def session_calibration(session: MeasuredSession, spec: FeatureSpec, calibration: str | Path | None,
                        mount: str = "") -> Calibration | None:
    """The sensor-path calibration a session uses (see :func:`assess_sessions`)."""
    if calibration is None:
        return None
    if calibration != "auto":
        return load_calibration(calibration)
    if session.bench is None:
        return None
    return find_calibration(calibration_key(session.bench, session.metadata, spec, mount))


def commanded_speed(session: MeasuredSession) -> float:
    """The commanded motor speed (rad/s) of a session (its metadata), else the measured one."""
    raw = session.metadata.get("session", {}).get("speed_rad_s")
    return float(raw) if raw is not None else motor_speed(session)


def _states(bench, candidates) -> tuple[WearState, ...]:
    if candidates is None:
        states = bench.states
    elif isinstance(candidates, (str, Path)):
        states = load_states(candidates, bench)
    else:
        states = tuple(candidates)
    if not states:
        raise ValueError(f"bench {bench.name!r} declares no [[state]] tables; give the candidate states "
                         "(--candidates STATES.toml)")
    return states


def assess_sessions(sessions: Sequence[str | Path | MeasuredSession], *,
                    candidates: str | Path | Sequence[WearState] | None = None,
                    settings: EnsembleSettings | None = None, options: IdentifyOptions | None = None,
                    compare_options: CompareOptions | None = None,
                    ensembles: Mapping[str, Ensemble] | None = None, scheduler: str | None = None,
                    workers: int | None = None, progress: str | None = "theory ensembles",
                    calibration: str | Path | None = "auto", mount: str = "") -> list[Assessment]:
    """Identify and compare each session (paths or ``MeasuredSession``) among candidate states.

    candidates: a ``[[state]]`` TOML file, ``WearState``s, or None for the states of the bench
    recorded in each session. Ensembles are built once per (bench, commanded speed) on the compute
    layer and cached; ``ensembles`` ({state: Ensemble}) uses those instead. Defaults: the default
    ensemble settings, identification options and comparison options.
    calibration: "auto" uses the stored calibration of each session's bench, sensor and ``mount``
    (``calibration.py``) when there is one, else the sensor-path prior; a calibration file uses that;
    None never uses one.
    """
    settings, options = settings or EnsembleSettings(), options or IdentifyOptions()
    compare_options = compare_options or CompareOptions()
    loaded, groups = _grouped(sessions, "candidate states need one" if ensembles is None else None)
    out: list[Assessment | None] = [None] * len(loaded)
    for idx in groups:
        first = loaded[idx[0]]
        ens = ensembles or build_ensembles(first.bench, _states(first.bench, candidates),
                                           speed=commanded_speed(first), settings=settings, scheduler=scheduler,
                                           workers=workers, progress=progress)
        st = next(iter(ens.values())).settings
        fitted: dict[str, object] = {}
        for i in idx:
            s = loaded[i]
            cal = session_calibration(s, st.features, calibration, mount)
            tag = cal.key if cal else ""
            if tag not in fitted:
                fitted[tag] = fit_states(ens, options, sensor=cal.path if cal else None)
            arrays = _arrays(s)
            ident = identify_features(session_features(s, st.features, arrays), fitted[tag], label=s.label)
            if cal is not None:
                ident.notes.append(f"sensor path: {cal.describe()}")
            state = ident.verdict if ident.verdict in ens else max(ident.posterior, key=ident.posterior.get)
            curves, peaks = cycle_curves(*arrays, grid=st.grid,
                                         filter_spec=parse_filter(st.curve_filter, remove_bias=False))
            bands = compare_bands(curves, peaks, ens[state], window=compare_options.windows.cycles)
            comparison = None
            if len(s.cycles) >= compare_options.windows.cycles:
                comparison = compare_session(s, ensemble_theory(ens[state], s.bench or first.bench),
                                             options=compare_options)
            out[i] = Assessment(s, ident, bands, comparison)
    return out


def calibrate_sessions(sessions: Sequence[str | Path | MeasuredSession], state: str, *,
                       candidates: str | Path | Sequence[WearState] | None = None,
                       settings: EnsembleSettings | None = None, options: IdentifyOptions | None = None,
                       ensembles: Mapping[str, Ensemble] | None = None, mount: str = "",
                       scheduler: str | None = None, workers: int | None = None,
                       progress: str | None = "theory ensembles") -> Calibration:
    """The sensor-path calibration of one bench from ``sessions`` recorded in the known ``state``
    (a ``[[state]]`` name of the bench or of ``candidates``); see ``calibration.py``. Not saved."""
    from dataclasses import replace

    settings, options = settings or EnsembleSettings(), options or IdentifyOptions()
    loaded = [s if isinstance(s, MeasuredSession) else load_session(s) for s in sessions]
    first = loaded[0]
    if first.bench is None:
        raise ValueError(f"session {first.label}: no bench file recorded in it; calibration needs one")
    for s in loaded[1:]:
        if s.bench is None or s.bench.sha256 != first.bench.sha256 or sensor_record(s.metadata) != sensor_record(
                first.metadata):
            raise ValueError(f"session {s.label}: another bench file or sensor than {first.label}; calibrate one "
                             "bench and sensor at a time")
    ens = ensembles or build_ensembles(first.bench, _states(first.bench, candidates), speed=commanded_speed(first),
                                       settings=settings, scheduler=scheduler, workers=workers, progress=progress)
    if state not in ens:
        raise ValueError(f"calibrate: --state {state!r}: expected one of the bench's states {list(ens)}")
    spec = next(iter(ens.values())).settings.features
    exact = fit_states(ens, replace(options, sensor_path="none"))
    key = calibration_key(first.bench, first.metadata, spec, mount)
    return fit_calibration([session_features(s, spec) for s in loaded], exact, state, key=key,
                           bench=first.bench.name, labels=[s.label for s in loaded], mount=mount)


def estimate_sessions(sessions: Sequence[str | Path | MeasuredSession], *, design: EstimatorDesign | None = None,
                      estimator: Estimator | None = None, options: IdentifyOptions | None = None,
                      calibration: str | Path | None = "auto", mount: str = "", scheduler: str | None = None,
                      workers: int | None = None, progress: str | None = "estimator") -> list[Estimate]:
    """Clearance and wear of each session (paths or ``MeasuredSession``) with credible intervals.

    The estimator of each (bench, commanded speed) is built once on the compute layer (or the
    shipped one used when its key matches; ``estimator`` uses that one); ``design`` defaults to
    ``EstimatorDesign()``. ``calibration``/``mount``: as :func:`assess_sessions`.
    """
    design, options = design or EstimatorDesign(), options or IdentifyOptions()
    loaded, groups = _grouped(sessions, "the estimator needs one" if estimator is None else None)
    out: list[Estimate | None] = [None] * len(loaded)
    for idx in groups:
        first = loaded[idx[0]]
        est = estimator or build_estimator(first.bench, design, speed=commanded_speed(first), scheduler=scheduler,
                                           workers=workers, progress=progress)
        fitted: dict[str, EstimatorModel] = {}
        for i in idx:
            s = loaded[i]
            cal = session_calibration(s, est.spec, calibration, mount)
            tag = cal.key if cal else ""
            if tag not in fitted:
                fitted[tag] = fit_estimator(est, options, sensor=cal.path if cal else None)
            out[i] = estimate_features(session_features(s, est.spec), fitted[tag], label=s.label)
            if cal is not None:
                out[i].notes.append(f"sensor path: {cal.describe()}")
    return out


def track_sessions(sessions: Sequence[str | Path | MeasuredSession], cycles_run: Sequence[float], *,
                   limit: float | None = None, design: EstimatorDesign | None = None,
                   estimator: Estimator | None = None, options: IdentifyOptions | None = None,
                   calibration: str | Path | None = "auto", mount: str = "", scheduler: str | None = None,
                   workers: int | None = None, progress: str | None = "estimator") -> Track:
    """Wear over one bench's life from ``sessions`` recorded after ``cycles_run`` cycles (see
    ``track.py``); ``limit``: a clearance limit (m). Other arguments as :func:`estimate_sessions`."""
    design, options = design or EstimatorDesign(), options or IdentifyOptions()
    loaded = [s if isinstance(s, MeasuredSession) else load_session(s) for s in sessions]
    first = loaded[0]
    if first.bench is None:
        raise ValueError(f"session {first.label}: no bench file recorded in it; tracking needs one")
    for s in loaded[1:]:
        if s.bench is None or s.bench.sha256 != first.bench.sha256:
            raise ValueError(f"session {s.label}: another bench file than {first.label}; track one bench at a time")
    est = estimator or build_estimator(first.bench, design, speed=commanded_speed(first), scheduler=scheduler,
                                       workers=workers, progress=progress)
    cal = session_calibration(first, est.spec, calibration, mount)
    model = fit_estimator(est, options, sensor=cal.path if cal else None)
    track = track_features([session_features(s, est.spec) for s in loaded], cycles_run, model,
                           coefficient=first.bench.wear.coefficient, limit=limit, labels=[s.label for s in loaded])
    if cal is not None:
        track.notes.append(f"sensor path: {cal.describe()}")
    return track


def write_assessment_report(assessments: Sequence[Assessment], out_dir: str | Path, *, threshold: float = 0.9,
                            title: str = "wearbench: which state explains each session"):
    """``report.html``, ``scores.json`` and figures for assessed sessions (``validation.report``)."""
    from wearbench.validation.identify_report import IdentifiedSession
    from wearbench.validation.report import write_report

    scored = [a for a in assessments if a.comparison is not None]
    if not scored:
        raise ValueError("report: no session has a scorable five-cycle window")
    return write_report([a.comparison for a in scored], out_dir, title=title, threshold=threshold,
                        identified=[IdentifiedSession(a.identification, a.bands) for a in assessments])
