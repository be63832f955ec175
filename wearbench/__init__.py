"""wearbench: mechanism test beds with worn revolute clearance joints.

The public API a lab's script or notebook uses; ``__all__`` is the contract (``tests/test_api.py``
lists it, the documentation's API page is generated from it). Names are imported on first use, so
``import wearbench`` stays fast. Deeper module paths keep working but are not what the docs teach.
"""

from __future__ import annotations

import importlib
from typing import Any

# public name -> "module:attribute" it is taken from
_FACE: dict[str, str] = {
    "Bench": "wearbench.bench.schema:Bench",
    "BenchError": "wearbench.bench.schema:BenchError",
    "load_bench": "wearbench.bench.load:load_bench",
    "simulate": "wearbench.model:simulate",
    "build_scene": "wearbench.model:build_scene",
    "MeasuredSession": "wearbench.validation.measurement.session:MeasuredSession",
    "load_session": "wearbench.validation.measurement.session:load_session",
    "compare": "wearbench.reports.comparison:compare_sessions",
    "identify": "wearbench.validation.workflows.assess:assess_sessions",
    "estimate": "wearbench.validation.workflows.measure:estimate_sessions",
    "track": "wearbench.validation.workflows.measure:track_sessions",
    "calibrate": "wearbench.validation.workflows.measure:calibrate_sessions",
}

__all__ = ["Bench", "BenchError", "MeasuredSession", "build_scene", "calibrate", "compare", "estimate", "identify",
           "load_bench", "load_session", "simulate", "track"]


def __getattr__(name: str) -> Any:
    try:
        module, attribute = _FACE[name].split(":")
    except KeyError:
        raise AttributeError(f"module 'wearbench' has no attribute {name!r}") from None
    value = getattr(importlib.import_module(module), attribute)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
