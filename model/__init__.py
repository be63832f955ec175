"""wearbench.model: planar multibody theory of linkages with (worn) revolute clearance joints.

Public API (the shared contract): :func:`build_scene`, :func:`simulate`, :class:`Scene`,
:class:`SimulationResult`, :class:`SimulationError`, the method registry :data:`METHODS`. Plots live
in ``wearbench.model.plots``. Names load on first use, so the command line reads ``model.methods``
without loading numba; the numba cache is configured by ``model.contact`` before any kernel exists.
"""

from __future__ import annotations

import importlib
from typing import Any

_PUBLIC = {"METHODS": "methods", "Method": "methods", "Scene": "scene", "Spring": "packing", "Torque": "packing",
           "build_scene": "scene", "SimulationError": "simulation", "SimulationResult": "simulation",
           "simulate": "simulation"}

__all__ = ["METHODS", "Method", "Scene", "SimulationError", "SimulationResult", "Spring", "Torque",
           "build_scene", "simulate"]


def __getattr__(name: str) -> Any:
    if name in _PUBLIC:
        return getattr(importlib.import_module(f"wearbench.model.{_PUBLIC[name]}"), name)
    raise AttributeError(f"module 'wearbench.model' has no attribute {name!r}")
