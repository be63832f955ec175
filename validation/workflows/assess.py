"""Assess recorded sessions against theory ensembles: which state, how well, and the report.

The workflow behind ``wearbench identify``, ``wearbench compare --candidates`` and the demo: load
the sessions, build (or load) one ensemble per candidate state for each bench and commanded speed
on the compute layer, identify each session (``identify.py``), compare its cycles with the band of
the identified state (``bands.py``), judge its five-cycle windows against every state's ensemble
windows (``windows.py``), and write the report when asked. Imports the validation modules; the model only through
the ensembles.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

from wearbench.bench.load import load_states
from wearbench.bench.schema import WearState
from wearbench.validation.comparison.bands import BandComparison, compare_bands
from wearbench.validation.comparison.windows import (
    MeasuredCurves,
    SessionWindows,
    WindowOptions,
    WindowTheory,
    measured_curves,
    score_windows,
    window_theory,
)
from wearbench.validation.inference.calibration import Calibration, session_calibration
from wearbench.validation.inference.ensemble import (
    Ensemble,
    EnsembleSettings,
    build_ensembles,
    check_ensembles_fit,
    load_ensembles,
)
from wearbench.validation.inference.estimate import Estimate
from wearbench.validation.inference.identify import (
    Identification,
    IdentifyOptions,
    StateModels,
    fit_states,
    identify_features,
)
from wearbench.validation.measurement.session import MeasuredSession, load_session

__all__ = ["Assessment", "assess_sessions", "judging_models"]


@dataclass
class Assessment:
    """One session: its identification, its band against the identified (or top) state, and its
    five-cycle windows against every candidate state (``windows[state]``; the identified or top
    state is ``state``)."""

    session: MeasuredSession
    identification: Identification
    bands: BandComparison
    windows: dict[str, SessionWindows]
    measured: MeasuredCurves
    estimate: Estimate | None = None  # clearance and wear with intervals (``measure.estimate_assessed``)

    @property
    def state(self) -> str:
        """The state the session's windows are judged against: the verdict, else the most probable."""
        r = self.identification
        return r.verdict if r.verdict in r.posterior else max(r.posterior, key=r.posterior.get)

    @property
    def decided(self) -> bool:
        """Whether the identification named a state (else the windows are shown, not a verdict)."""
        return self.identification.verdict in self.identification.posterior










def candidate_states(bench, candidates) -> tuple[WearState, ...]:
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


def _source_digest() -> str:
    """Digest of the validation code a calibration depends on (a change of it is a cache miss)."""
    from wearbench.validation.comparison import windows
    from wearbench.validation.inference import identify, relative_states, sensor_path, statistics
    from wearbench.validation.measurement import features

    text = b"".join(Path(m.__file__).read_bytes()
                    for m in (identify, relative_states, statistics, sensor_path, windows, features))
    return hashlib.sha256(text).hexdigest()


def judging_models(ensembles: Mapping[str, Ensemble], options: IdentifyOptions, window_options: WindowOptions,
                   crank_speed: float, calibration: Calibration | None = None
                   ) -> tuple[StateModels, dict[str, WindowTheory]]:
    """The fitted state statistics (``identify.fit_states`` with the options' sensor path, or the bench's
    ``calibration``'s fitted path) and every state's window theory
    (their held-out nulls): the costly part of judging a session, computed once per ensembles'
    content, options, calibration and code, and kept in the result cache (``$WEARBENCH_CACHE``)."""
    from wearbench.compute.task_cache import MISSING, cache_load, cache_store, task_key

    key = task_key("window-calibration", _source_digest(),
                   {n: (e.features, e.curves, e.speed) for n, e in ensembles.items()}, asdict(options),
                   asdict(window_options), round(float(crank_speed), 9), asdict(calibration) if calibration else None)
    hit = cache_load(key)
    if hit is not MISSING:
        return hit
    models = fit_states(ensembles, options, window_cycles=window_options.cycles,
                        sensor=calibration.path if calibration else None)
    theories = {name: window_theory(e, crank_speed=crank_speed, models=models, options=window_options)
                for name, e in ensembles.items()}
    try:
        cache_store(key, (models, theories))
    except OSError:  # a read-only or full cache: computed again next time
        pass
    return models, theories


def assess_sessions(sessions: Sequence[str | Path | MeasuredSession], *,
                    candidates: str | Path | Sequence[WearState] | None = None,
                    settings: EnsembleSettings | None = None, options: IdentifyOptions | None = None,
                    window_options: WindowOptions | None = None,
                    ensembles: Mapping[str, Ensemble] | str | Path | None = None, scheduler: str | None = None,
                    workers: int | None = None, progress: str | None = "theory ensembles",
                    calibration: str | Path | None = "auto", mount: str = "") -> list[Assessment]:
    """Identify and compare each session (paths or ``MeasuredSession``) among candidate states.

    candidates: a ``[[state]]`` TOML file, ``WearState``s, or None for the states of the bench
    recorded in each session. Ensembles are built once per (bench, commanded speed) on the compute
    layer and cached; ``ensembles`` ({state: Ensemble}, or a file saved by ``wearbench ensemble``,
    refused where its bench, speed or candidates do not fit a session) uses those instead. Defaults:
    the default ensemble settings, identification options and window options.
    calibration: "auto" uses the stored calibration of each session's bench, sensor and ``mount``
    (``calibration.py``) when there is one, else the sensor-path prior; a calibration file uses that;
    None never uses one.
    """
    settings, options = settings or EnsembleSettings(), options or IdentifyOptions()
    ensembles_file = None
    if isinstance(ensembles, (str, Path)):
        ensembles_file, ensembles = Path(ensembles), load_ensembles(ensembles)
    window_options = window_options or WindowOptions()
    loaded = [s if isinstance(s, MeasuredSession) else load_session(s) for s in sessions]
    groups: dict[tuple, list[int]] = {}
    for i, s in enumerate(loaded):
        if s.bench is None and ensembles is None:
            why = next((p for p in (s.problem or "").split("; ") if "bench" in p), "no bench file recorded in it")
            raise ValueError(f"session {s.label}: {why}; candidate states need its bench")
        groups.setdefault((s.bench.sha256 if s.bench else "", round(s.commanded_speed, 6)), []).append(i)
    out: list[Assessment | None] = [None] * len(loaded)
    for idx in groups.values():
        first = loaded[idx[0]]
        if ensembles_file is not None:
            states = candidate_states(first.bench, candidates) if first.bench and (candidates or first.bench.states) else None
            check_ensembles_fit(ensembles_file, ensembles, bench=first.bench, states=states,
                                speed=first.commanded_speed, session=first.label)
        ens = ensembles or build_ensembles(first.bench, candidate_states(first.bench, candidates),
                                           speed=first.commanded_speed, settings=settings, scheduler=scheduler,
                                           workers=workers, progress=progress)
        st = next(iter(ens.values())).settings
        bench = first.bench
        crank = next(iter(ens.values())).speed * (bench.encoder_driver.ratio if bench is not None else 1.0)
        judged: dict[str, tuple] = {}
        for i in idx:
            s = loaded[i]
            cal = session_calibration(s, st.features, calibration, mount)
            tag = cal.key if cal else ""
            if tag not in judged:
                judged[tag] = judging_models(ens, options, window_options, crank, cal)
            models, theories = judged[tag]
            feats = s.features(st.features)
            ident = identify_features(feats, models, label=s.label)
            if cal is not None:
                ident.notes.append(f"sensor path: {cal.describe()}")
            state = ident.verdict if ident.verdict in ens else max(ident.posterior, key=ident.posterior.get)
            mc = measured_curves(*s.samples, grid=st.grid, filter_spec=st.curve_filter,
                                 lowpass=window_options.delay_lowpass, fs=s.fs, stream_start=s.stream_start)
            bands = compare_bands(mc.at(0.0), mc.peaks, ens[state])
            stated = s.stated_delay()
            windows = {name: score_windows(mc, th, feats, stated) for name, th in theories.items()}
            out[i] = Assessment(s, ident, bands, windows, mc)
    return out
