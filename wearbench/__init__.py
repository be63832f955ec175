"""wearbench: mechanism test beds with worn revolute clearance joints.

The public API a lab's script or notebook uses; ``__all__`` is the contract (``tests/test_api.py``
lists it, the documentation's API page is generated from it). Names load with their module on first
use, so ``import wearbench`` stays fast. Deeper module paths work too, but they are not what the
documentation teaches and they move as the code does.

>>> import wearbench
>>> bench = wearbench.load_bench("ninebar-testbed")
>>> found = wearbench.estimate(["session.mcap"])            # doctest: +SKIP
>>> found.to_dataframe()                                     # doctest: +SKIP
"""

from __future__ import annotations

import importlib
from typing import Any

# public name -> "module:attribute" it is taken from
_FACE: dict[str, str] = {
    # benches and the model
    "Bench": "wearbench.bench.schema:Bench",
    "BenchError": "wearbench.bench.schema:BenchError",
    "load_bench": "wearbench.api:load_bench",
    "simulate": "wearbench.api:simulate",
    "SimulationResult": "wearbench.model.simulation:SimulationResult",
    "SimulationError": "wearbench.model.simulation:SimulationError",
    # sessions
    "record": "wearbench.api:record",
    "SessionResult": "wearbench.acquisition.session:SessionResult",
    "load_session": "wearbench.validation.measurement.session:load_session",
    "MeasuredSession": "wearbench.validation.measurement.session:MeasuredSession",
    "SessionSet": "wearbench.validation.workflows.session_set:SessionSet",
    # comparison, identification, estimation, tracking, calibration
    "compare": "wearbench.api:compare",
    "identify": "wearbench.api:identify",
    "estimate": "wearbench.api:estimate",
    "track": "wearbench.api:track",
    "calibrate": "wearbench.api:calibrate",
    "write_report": "wearbench.api:write_report",
    "Results": "wearbench.api:Results",
    "SessionComparison": "wearbench.validation.comparison.compare:SessionComparison",
    "Assessment": "wearbench.validation.workflows.assess:Assessment",
    "Identification": "wearbench.validation.inference.identify:Identification",
    "Estimate": "wearbench.validation.estimation.estimate:Estimate",
    "Interval": "wearbench.validation.estimation.estimate:Interval",
    "Track": "wearbench.validation.estimation.track:Track",
    "Calibration": "wearbench.validation.inference.calibration:Calibration",
    "save_calibration": "wearbench.validation.inference.calibration:save_calibration",
    # theory built ahead of time, and how
    "EnsembleSettings": "wearbench.validation.inference.ensemble:EnsembleSettings",
    "build_ensembles": "wearbench.validation.inference.ensemble:build_ensembles",
    "load_ensembles": "wearbench.validation.inference.ensemble:load_ensembles",
    "EstimatorDesign": "wearbench.validation.estimation.estimate:EstimatorDesign",
    "Estimator": "wearbench.validation.estimation.estimate:Estimator",
    "build_estimator": "wearbench.validation.estimation.estimate:build_estimator",
    "load_estimator": "wearbench.validation.estimation.estimate:load_estimator",
    "SpreadDesign": "wearbench.validation.estimation.spread:SpreadDesign",
    "ArtefactError": "wearbench.validation.inference.artefacts:ArtefactError",
    "Compute": "wearbench.compute.options:Compute",
}

__all__ = ["ArtefactError", "Assessment", "Bench", "BenchError", "Calibration", "Compute", "EnsembleSettings",
           "Estimate", "Estimator", "EstimatorDesign", "Identification", "Interval", "MeasuredSession", "Results",
           "SessionComparison", "SessionResult", "SessionSet", "SimulationError", "SimulationResult", "SpreadDesign", "Track",
           "build_ensembles", "build_estimator", "calibrate", "compare", "estimate", "identify", "load_bench",
           "load_ensembles", "load_estimator", "load_session", "record", "save_calibration", "simulate", "track",
           "write_report"]


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
