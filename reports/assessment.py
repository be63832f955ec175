"""The report of assessed sessions (``wearbench identify --out``, ``compare`` on a bench with
states, the demo): each session's identification, bands, windows and estimate, on one page."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path

from wearbench.reports.comparison import ComparisonReport, write_report
from wearbench.reports.identification import IdentifiedSession
from wearbench.validation.workflows.assess import Assessment

__all__ = ["write_assessment_report"]


def write_assessment_report(assessments: Sequence[Assessment], out_dir: str | Path, *, threshold: float = 0.9,
                            title: str = "wearbench: which state explains each session") -> ComparisonReport:
    """``report.html``, ``scores.json`` and figures for assessed sessions, in ``out_dir``."""
    if not assessments:
        raise ValueError("report: no assessed session")
    first = next(iter(assessments[0].windows.values()))
    st = first.options
    options = {"filter": "CFC 180 (the ensemble's curves)",
               "windows": f"all consecutive {st.cycles}-cycle windows of steady cycles", **asdict(st)}
    return write_report([], out_dir, title=title, threshold=threshold, options=options,
                        identified=[IdentifiedSession(a.identification, a.bands, a.windows, a.state, a.decided,
                                                      a.estimate) for a in assessments])
