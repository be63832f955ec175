"""Assess recorded sessions against theory ensembles: which state, how well, and the report.

The workflow behind ``wearbench identify``, ``wearbench compare --candidates`` and the demo: load
the sessions, build (or load) one ensemble per candidate state for each bench and commanded speed
on the compute layer, identify each session (``identify.py``), compare its cycles with the band of
the identified state (``bands.py``), score its five-cycle windows against that state's ensemble
median, and write the report when asked. Imports the validation modules; the model only through
the ensembles.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from wearbench.acquisition.layout import clip_level, recorded_clip_level
from wearbench.bench.load import load_states
from wearbench.bench.schema import WearState
from wearbench.validation.bands import BandComparison, compare_bands, ensemble_theory
from wearbench.validation.compare import (
    CompareOptions,
    SessionComparison,
    compare_session,
    motor_speed,
)
from wearbench.validation.ensemble import (
    Ensemble,
    EnsembleSettings,
    build_ensembles,
    check_ensembles_fit,
    load_ensembles,
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

__all__ = ["Assessment", "assess_sessions", "session_clip_level", "session_features"]


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
    """Cycle features of a measured session; clipped samples counted by the recorder's rule at the
    range the session recorded in its calibration (a session without one: its bench file's range).
    ``arrays``: the session's ``_arrays`` when the caller has them already."""
    return cycle_features(*(arrays or _arrays(session)), spec or FeatureSpec(), clip_level=session_clip_level(session))


def session_clip_level(session: MeasuredSession) -> float | None:
    """|a| from which a sample of ``session`` is clipped (``acquisition.layout.clip_level``) from its
    recorded calibration (range, LSB), else its bench file's accelerometer range; None if neither."""
    level = recorded_clip_level(session.metadata.get("calibration", {}))
    if math.isfinite(level):
        return level
    try:
        return clip_level(session.bench.sensor("accelerometer").range) if session.bench is not None else None
    except KeyError:
        return None


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
                    ensembles: Mapping[str, Ensemble] | str | Path | None = None, scheduler: str | None = None,
                    workers: int | None = None, progress: str | None = "theory ensembles") -> list[Assessment]:
    """Identify and compare each session (paths or ``MeasuredSession``) among candidate states.

    candidates: a ``[[state]]`` TOML file, ``WearState``s, or None for the states of the bench
    recorded in each session. Ensembles are built once per (bench, commanded speed) on the compute
    layer and cached; ``ensembles`` ({state: Ensemble}, or a file saved by ``wearbench ensemble``,
    refused where its bench, speed or candidates do not fit a session) uses those instead. Defaults:
    the default ensemble settings, identification options and comparison options.
    """
    settings, options = settings or EnsembleSettings(), options or IdentifyOptions()
    ensembles_file = None
    if isinstance(ensembles, (str, Path)):
        ensembles_file, ensembles = Path(ensembles), load_ensembles(ensembles)
    compare_options = compare_options or CompareOptions()
    loaded = [s if isinstance(s, MeasuredSession) else load_session(s) for s in sessions]
    groups: dict[tuple, list[int]] = {}
    for i, s in enumerate(loaded):
        if s.bench is None and ensembles is None:
            why = next((p for p in (s.problem or "").split("; ") if "bench" in p), "no bench file recorded in it")
            raise ValueError(f"session {s.label}: {why}; candidate states need its bench")
        groups.setdefault((s.bench.sha256 if s.bench else "", round(commanded_speed(s), 6)), []).append(i)
    out: list[Assessment | None] = [None] * len(loaded)
    for idx in groups.values():
        first = loaded[idx[0]]
        if ensembles_file is not None:
            states = _states(first.bench, candidates) if first.bench and (candidates or first.bench.states) else None
            check_ensembles_fit(ensembles_file, ensembles, bench=first.bench, states=states,
                                speed=commanded_speed(first), session=first.label)
        ens = ensembles or build_ensembles(first.bench, _states(first.bench, candidates),
                                           speed=commanded_speed(first), settings=settings, scheduler=scheduler,
                                           workers=workers, progress=progress)
        models = fit_states(ens, options)
        st = next(iter(ens.values())).settings
        for i in idx:
            s = loaded[i]
            arrays = _arrays(s)
            ident = identify_features(session_features(s, st.features, arrays), models, label=s.label)
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
