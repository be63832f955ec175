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

from wearbench.bench.schema import WearState
from wearbench.compute.options import Compute
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
from wearbench.validation.estimation.estimate import Estimate
from wearbench.validation.inference.calibration import Calibration
from wearbench.validation.inference.ensemble import (
    Ensemble,
    EnsembleSettings,
    EnsembleSize,
)
from wearbench.validation.inference.identify import (
    Identification,
    IdentifyOptions,
    StateModels,
    fit_states,
    identify_features,
)
from wearbench.validation.measurement.scaling import resolve_analysis
from wearbench.validation.measurement.session import MeasuredSession
from wearbench.validation.workflows.session_set import SessionSet

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

    def to_dict(self) -> dict:
        """The identification, each state's window verdict and the estimate, as JSON-able data."""
        return {**self.identification.to_dict(),
                "windows": {state: w.summary() for state, w in self.windows.items()},
                **({"estimate": self.estimate.to_dict()} if self.estimate else {})}

    def row(self) -> dict:
        """One table row: the identification's, and the estimate's columns when there is one."""
        row = self.identification.row()
        if self.estimate is not None:
            row.update({k: v for k, v in self.estimate.row().items() if k not in ("session", "cycles")})
        return row












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


def assess_sessions(sessions: SessionSet | Sequence[str | Path | MeasuredSession], *,
                    candidates: str | Path | Sequence[WearState] | None = None,
                    settings: EnsembleSettings | EnsembleSize | None = None, options: IdentifyOptions | None = None,
                    window_options: WindowOptions | None = None,
                    ensembles: Mapping[str, Ensemble] | str | Path | None = None, compute: Compute | None = None,
                    calibration: str | Path | None = "auto", mount: str = "") -> list[Assessment]:
    """Identify and compare each session (paths, ``MeasuredSession``s or a ``SessionSet``) among
    candidate states.

    candidates: a ``[[state]]`` TOML file, ``WearState``s, or None for the states of the bench
    recorded in each session. Ensembles of ``settings`` (an ``EnsembleSize`` or None: resolved for each
    bench and commanded speed, ``EnsembleSettings.for_bench``; every group's checked before any is
    built) are built once per (bench, commanded speed) on the compute layer (``compute``) and cached; ``ensembles`` ({state: Ensemble}, or a file saved by ``wearbench
    ensemble``, refused before anything is built where its bench, speed or candidates do not fit a
    session) uses those instead. calibration: "auto" uses the stored calibration of each session's
    bench, sensor and ``mount`` when there is one, else the sensor-path prior; a calibration file uses
    that; None never uses one. Defaults: the default settings and options.
    """
    options, window_options = options or IdentifyOptions(), window_options or WindowOptions()
    sessions = SessionSet.of(sessions, calibration=calibration, mount=mount)
    if ensembles is None:
        sessions.require_benches("candidate states need its bench")
    sessions.check_artefacts(ensembles=ensembles, candidates=candidates, settings=settings, theory=("ensembles",),
                             cycles=window_options.cycles)
    out: list[Assessment | None] = [None] * len(sessions)
    for group in sessions.groups():
        ens = sessions.ensembles(group, candidates=candidates, settings=settings, ensembles=ensembles,
                                 compute=compute)
        st = next(iter(ens.values())).settings
        crank = next(iter(ens.values())).speed * (group.bench.encoder_driver.ratio if group.bench else 1.0)
        analysis = resolve_analysis(group.bench, group.speed)  # the windows at this crank speed
        wo = window_options.for_crank(analysis.crank_hz, analysis.window_lowpass)
        judged: dict[str, tuple] = {}
        for i, s in zip(group.indices, group.sessions, strict=True):
            cal = sessions.calibration(s, st.features)
            tag = cal.key if cal else ""
            if tag not in judged:
                judged[tag] = judging_models(ens, options, wo, crank, cal)
            models, theories = judged[tag]
            feats = sessions.features(s, st.features)
            ident = identify_features(feats, models, label=s.label)
            if cal is not None:
                ident.notes.append(f"sensor path: {cal.describe()}")
            for note in (analysis.speed_note(), s.resolution_note(feats)):
                if note:
                    ident.notes.append(note)
            state = ident.verdict if ident.verdict in ens else max(ident.posterior, key=ident.posterior.get)
            mc = measured_curves(*s.samples, grid=st.grid, filter_spec=st.curve_filter,
                                 lowpass=wo.delay_lowpass, fs=s.fs, stream_start=s.stream_start)
            bands = compare_bands(mc.at(0.0), mc.peaks, ens[state])
            windows = {name: score_windows(mc, th, feats, s.stated_delay()) for name, th in theories.items()}
            out[i] = Assessment(s, ident, bands, windows, mc)
    return out
