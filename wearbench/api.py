"""The calls of the public API that are more than a name taken from a package: a bench by name or
path, a simulation from a bench, a recording in one call, and the validation workflows with the
options a lab sets, returning lists that turn into tables.

Everything here wires the packages below; nothing computes. The validation workflows run their
linear algebra on one BLAS thread (``compute.threads``), as the command line does. Imports every
library layer.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pandas as pd

from wearbench.bench.schema import Bench, WearState
from wearbench.compute.options import Compute
from wearbench.compute.threads import on_one_blas_thread

if TYPE_CHECKING:
    from wearbench.validation.comparison.compare import CompareOptions
    from wearbench.validation.estimation.estimate import Estimator, EstimatorDesign
    from wearbench.validation.inference.ensemble import EnsembleSettings

__all__ = ["Results", "calibrate", "compare", "estimate", "identify", "load_bench", "record", "simulate", "track",
           "write_report"]

Sessions = Sequence[str | Path] | Any  # paths, MeasuredSessions or a SessionSet


class Results(list):
    """A list of per-session results (identifications, estimates, comparisons) that makes a table:
    :meth:`to_dataframe` has one row per session, :meth:`to_dict` one dict per session."""

    def to_dict(self) -> list[dict]:
        return [r.to_dict() for r in self]

    def to_dataframe(self) -> pd.DataFrame:
        return pd.DataFrame([r.row() for r in self]).set_index("session")


def load_bench(bench: str | Path) -> Bench:
    """A bench file by path, or a shipped bench by name (``"ninebar-testbed"``), read and validated
    (``BenchError`` naming the file, key, value and what was expected)."""
    from wearbench.bench.load import load_bench as load
    from wearbench.bench.load import resolve_bench

    return load(resolve_bench(bench))


def _bench(bench: Bench | str | Path) -> Bench:
    return bench if isinstance(bench, Bench) else load_bench(bench)


def simulate(bench: Bench | str | Path, *, clearances: Mapping[str, float | None] | None = None,
             revolutions: float = 3.0, speed: float | None = None, **options):
    """Simulate ``bench`` (a ``Bench``, a file or a shipped name) for ``revolutions`` crank
    revolutions at motor ``speed`` (rad/s; default the bench's). ``clearances``: {joint: m, or None
    for an ideal pin} over the bench file's. Other options as :func:`wearbench.model.simulate`
    (``method``, ``t_end``, ``output_rate``, ``record_contacts``, ...). Returns its
    ``SimulationResult``: ``result.table`` is a DataFrame, one row per output time (SI units)."""
    from wearbench.model import build_scene
    from wearbench.model import simulate as run

    scene = build_scene(_bench(bench), clearances=clearances)
    return run(scene, revolutions=revolutions, speed=speed, **options)


def record(bench: Bench | str | Path, out: str | Path, *, cycles: float | None = None, duration: float | None = None,
           backend: str | None = None, options: Mapping[str, Any] | None = None, speed: float | None = None,
           cycles_run: float | None = None, operator: str = "", force: bool = False):
    """Record one session of ``bench`` to the MCAP file ``out``: ``cycles`` crank cycles or ``duration``
    s, through ``backend`` (default the bench file's: ``sim``, ``serial``, ``can``, ``canopen``,
    ``nidaqmx``) with its ``options`` over the bench file's ``[hardware.BACKEND]``. An existing
    ``out`` is replaced only with ``force``. Returns the recorder's ``SessionResult``; an
    interrupted session leaves a valid file up to that point."""
    from wearbench.acquisition.backends import open_rig
    from wearbench.acquisition.recorder import record_session
    from wearbench.acquisition.session import SessionPlan
    from wearbench.acquisition.session_writer import SessionWriter

    bench = _bench(bench)
    plan = SessionPlan(speed=bench.speed if speed is None else speed, cycles=cycles, duration=duration,
                       cycles_run=cycles_run, operator=operator)
    writer = SessionWriter(out, replace=force)
    return record_session(open_rig(bench, backend, options), bench, plan, out, writer=writer)


@on_one_blas_thread
def identify(sessions: Sessions, *, candidates: str | Path | Sequence[WearState] | None = None,
             ensembles: Mapping | str | Path | None = None, settings: EnsembleSettings | None = None,
             estimator: Estimator | EstimatorDesign | str | Path | None = None, threshold: float = 0.9,
             calibration: str | Path | None = "auto", mount: str = "", compute: Compute | None = None) -> Results:
    """Which candidate state explains each session, with posterior probabilities (``Assessment``s:
    ``.identification``, ``.bands``, ``.windows``, and ``.estimate`` when ``estimator`` is given: an
    ``Estimator``, its file, or an ``EstimatorDesign``). Ensembles are ``ensembles`` (a file or a
    mapping), else built on ``compute`` with ``settings`` (default: each bench's own at its sessions'
    speed, ``EnsembleSettings.for_bench``; the shipped ones when they fit), every batch announced with
    its CPU time first. See the docs' "How identification works"."""
    from wearbench.validation.estimation.estimate import EstimatorDesign, load_estimator
    from wearbench.validation.inference.identify import IdentifyOptions
    from wearbench.validation.workflows.assess import assess_sessions
    from wearbench.validation.workflows.measure import estimate_assessed
    from wearbench.validation.workflows.session_set import SessionSet

    if isinstance(estimator, (str, Path)):
        estimator = load_estimator(estimator)
    options = IdentifyOptions(threshold=threshold)
    sessions = SessionSet.of(sessions, calibration=calibration, mount=mount)
    sessions.check_artefacts(ensembles=ensembles, candidates=candidates,
                             estimator=None if estimator is None or isinstance(estimator, EstimatorDesign) else estimator)
    assessed = assess_sessions(sessions, candidates=candidates, ensembles=ensembles, settings=settings,
                               options=options, compute=compute)
    if estimator is not None:
        estimate_assessed(assessed, estimator, options=options, calibration=calibration, mount=mount, compute=compute)
    return Results(assessed)


@on_one_blas_thread
def estimate(sessions: Sessions, *, estimator: Estimator | str | Path | None = None,
             design: EstimatorDesign | None = None, calibration: str | Path | None = "auto",
             mount: str = "", compute: Compute | None = None) -> Results:
    """Clearance, cycles run and wear depth of each session with credible intervals (``Estimate``s),
    from ``estimator`` (an ``Estimator`` or its file) or the estimator of ``design`` (default: each
    bench's own, ``EstimatorDesign.for_bench``; its shipped one when it fits, else built on
    ``compute``)."""
    from wearbench.validation.workflows.measure import estimate_sessions

    return Results(estimate_sessions(sessions, design=design, estimator=estimator, calibration=calibration,
                                     mount=mount, compute=compute))


@on_one_blas_thread
def track(sessions: Sessions, cycles_run: Sequence[float] | None = None, *, limit: float | None = None,
          estimator: Estimator | str | Path | None = None, design: EstimatorDesign | None = None,
          calibration: str | Path | None = "auto", mount: str = "",
          move: bool = True, compute: Compute | None = None):
    """A bench's wear over its life from sessions recorded after ``cycles_run`` cycles (default: as
    each session recorded it): the initial clearance, the wear coefficient, the wear depth at each
    session and, with ``limit`` (m), the cycles until the clearance reaches it (a ``Track``)."""
    from wearbench.validation.workflows.measure import track_sessions

    return track_sessions(sessions, cycles_run, limit=limit, design=design, estimator=estimator,
                          calibration=calibration, mount=mount, move=move, compute=compute)


@on_one_blas_thread
def calibrate(sessions: Sessions, state: str, *, candidates: str | Path | Sequence[WearState] | None = None,
              ensembles: Mapping | str | Path | None = None, settings: EnsembleSettings | None = None,
              mount: str = "", compute: Compute | None = None):
    """The sensor-path calibration of one bench from sessions recorded in the known ``state`` (a
    ``Calibration``; not stored: ``save_calibration`` stores it where ``identify`` and ``estimate``
    find it); ensembles as :func:`identify` builds them."""
    from wearbench.validation.workflows.measure import calibrate_sessions

    return calibrate_sessions(sessions, state, candidates=candidates, ensembles=ensembles, settings=settings,
                              mount=mount, compute=compute)


@on_one_blas_thread
def compare(sessions: Sessions, theory: Sequence | None = None, *, options: CompareOptions | None = None) -> Results:
    """Each session scored window by window against one theory (simulated from its bench at the
    measured speed, or ``theory``: one table for all sessions or one per session), the paper's
    comparison: ``SessionComparison``s (``.windows``, ``.summary``). ``write_report`` writes them."""
    from wearbench.validation.comparison.compare import CompareOptions, compare_session

    theories = list(theory) if theory is not None else [None]
    if len(theories) == 1:
        theories = theories * len(sessions)
    if len(theories) != len(sessions):
        raise ValueError(f"compare: {len(theories)} theories for {len(sessions)} sessions; give one, or one per session")
    return Results(compare_session(s, t, options=options or CompareOptions()) for s, t in zip(sessions, theories,
                                                                                               strict=True))


def write_report(results: Sequence, out: str | Path, *, title: str | None = None, force: bool = False):
    """``report.html`` (self-contained), ``scores.json`` and the figures of :func:`identify` or
    :func:`compare` results, in the folder ``out`` (a folder with files in it only with ``force``; the
    old files stay until the new ones are complete). Returns the report (``.html``, ``.figures``)."""
    from wearbench.bench.output_file import output_folder
    from wearbench.reports.assessment import write_assessment_report
    from wearbench.reports.comparison import write_report as write_comparisons
    from wearbench.validation.workflows.assess import Assessment

    if not results:
        raise ValueError("write_report: no results")
    assessed = all(isinstance(r, Assessment) for r in results)
    with output_folder(out, force=force) as tmp:
        titled = {"title": title} if title else {}
        report = write_assessment_report(results, tmp, **titled) if assessed else write_comparisons(list(results), tmp,
                                                                                                    **titled)
    return report.moved_to(out)
