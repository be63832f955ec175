"""wearbench.model: planar multibody theory of linkages with (worn) revolute clearance joints.

Public API (the shared contract): :func:`build_scene`, :func:`simulate`, :class:`Scene`,
:class:`SimulationResult`, :class:`SimulationError`. Plots live in ``wearbench.model.plots``.
"""

from wearbench.model.jit_cache import configure_numba_cache

configure_numba_cache()  # before any kernel is compiled: the cache is keyed on the model's source

from wearbench.model.integrators import METHODS, Method
from wearbench.model.scene import Scene, Spring, Torque, build_scene
from wearbench.model.simulate import SimulationError, SimulationResult, simulate

__all__ = ["METHODS", "Method", "Scene", "SimulationError", "SimulationResult", "Spring", "Torque",
           "build_scene", "simulate"]
