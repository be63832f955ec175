"""wearbench.model: planar multibody theory of linkages with (worn) revolute clearance joints.

Public API (the shared contract): :func:`build_scene`, :func:`simulate`, :class:`Scene`,
:class:`SimulationResult`, :class:`SimulationError`, the method registry :data:`METHODS`. The
package holds dynamics, contact and wear only: batches run on ``wearbench.compute``, studies, sweeps
and figures live in ``wearbench.studies``. The numba cache is keyed on the model's source here,
before any submodule decorates a kernel.
"""

from __future__ import annotations

from wearbench.model.jit_cache import configure_numba_cache

configure_numba_cache()  # before the first kernel is decorated: every submodule import runs this file first

from wearbench.model.methods import METHODS, Method
from wearbench.model.packing import Spring, Torque
from wearbench.model.scene import Scene, build_scene
from wearbench.model.simulation import SimulationError, SimulationResult, simulate

__all__ = ["METHODS", "Method", "Scene", "SimulationError", "SimulationResult", "Spring", "Torque",
           "build_scene", "simulate"]
