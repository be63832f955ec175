"""wearbench.validation: measured sessions against theory: scores, identification, estimates.

Cut by job, each group a subpackage on its own floor: ``measurement`` (a session and its cycle
features), ``inference`` (ensembles, identification, calibration), ``estimation`` (the estimator,
the move from new to worn, tracking), ``comparison`` (window scores and verdicts against theory),
``workflows`` (sessions in, answers out). Figures and HTML live above it, in :mod:`wearbench.reports`. The names below load with their
module on first use; a lab's code uses :mod:`wearbench` itself.
"""

from importlib import import_module
from typing import Any

_WHERE = {
    "comparison.compare": ("CompareOptions", "SessionComparison", "TheoryRanking", "WindowResult",
                           "compare_session", "rank_theories"),
    "comparison.metrics": ("WindowScores", "iso18571", "score_window"),
    "measurement.cycles": ("WindowSpec", "parse_windows"),
    "measurement.filters": ("FilterSpec", "parse_filter"),
    "measurement.session": ("MeasuredSession", "load_session"),
}
_MODULE = {name: module for module, names in _WHERE.items() for name in names}

__all__ = ["CompareOptions", "FilterSpec", "MeasuredSession", "SessionComparison", "TheoryRanking", "WindowResult",
           "WindowScores", "WindowSpec", "compare_session", "iso18571", "load_session", "parse_filter", "parse_windows",
           "rank_theories", "score_window"]


def __getattr__(name: str) -> Any:
    if name not in _MODULE:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(f"{__name__}.{_MODULE[name]}"), name)
    globals()[name] = value
    return value
