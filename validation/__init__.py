"""wearbench.validation: align, filter and score measured sessions against theory; reports.

Public API: :func:`compare_session`, :func:`compare_sessions` (writes the report),
:func:`rank_theories` (which candidate theory explains a session best), :class:`CompareOptions`,
:func:`load_session`, :func:`score_window`, :func:`iso18571`, :func:`parse_filter`,
:func:`parse_windows`. Module map: filters (CFC/Butterworth), dtw (banded DTW), alignment (lag
search), metrics (scores), cycles (crank cycles, windows), measured (session data), theory
(simulated or loaded theory by crank angle), compare (pipeline), report (HTML/JSON/PNG), windows
(five-cycle windows against an ensemble's own windows, with a verdict), window_report (their
figures and tables).
"""

from wearbench.validation.compare import (
                                          CompareOptions,
                                          SessionComparison,
                                          TheoryRanking,
                                          WindowResult,
                                          compare_session,
                                          rank_theories,
)
from wearbench.validation.cycles import WindowSpec, parse_windows
from wearbench.validation.filters import FilterSpec, parse_filter
from wearbench.validation.measured import MeasuredSession, load_session
from wearbench.validation.metrics import WindowScores, iso18571, score_window
from wearbench.validation.report import compare_sessions

__all__ = ["CompareOptions", "FilterSpec", "MeasuredSession", "SessionComparison", "TheoryRanking",
           "WindowResult", "WindowScores", "WindowSpec", "compare_session", "compare_sessions", "iso18571",
           "load_session", "parse_filter", "parse_windows", "rank_theories", "score_window"]
