"""wearbench.studies: the paper's studies, parameter sweeps and their figures, built on the model.

``study`` runs the wear and clearance studies of a bench, ``sweep`` a grid of design points, each as
tasks of :mod:`wearbench.compute`; ``plots``, ``study_plots`` and ``wear_report`` draw and write their
results. Stands above ``model`` and ``compute``; nothing below imports it.
"""

from __future__ import annotations

import functools
from pathlib import Path

from wearbench.model.digest import package_source_digest

__all__ = ["studies_source_digest"]


@functools.cache
def studies_source_digest() -> str:
    """SHA-256 (hex) over the source of every module of ``wearbench.studies``: a study's or sweep's
    task key holds it (``compute.task_key`` holds the model's), so changed study code never replays a
    cached result."""
    return package_source_digest(Path(__file__).parent)
