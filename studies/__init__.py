"""wearbench.studies: the paper's studies, parameter sweeps and their figures, built on the model.

``study`` runs the wear and clearance studies of a bench, ``sweep`` a grid of design points, each as
tasks of :mod:`wearbench.compute`; ``plots``, ``study_plots`` and ``wear_report`` draw and write their
results. Stands above ``model`` and ``compute``; nothing below imports it.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
from collections.abc import Callable

__all__ = ["tasks_source_digest"]


@functools.cache
def tasks_source_digest(*functions: Callable) -> str:
    """SHA-256 (hex) over the source of the ``functions`` a study's or sweep's tasks run: every task
    key holds it (``compute.task_key`` holds the model's digest too), so changed simulation code never
    replays a cached result, and changed statistics, reports or figures reuse the cached runs."""
    return hashlib.sha256("".join(inspect.getsource(f) for f in functions).encode()).hexdigest()
