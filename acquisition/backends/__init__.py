"""Backends by name: the module of each name in the bench vocabulary ``BACKENDS`` (bench/schema.py)
has ``open_rig(bench, options) -> Rig``; adding a backend is adding its name there and its module here.

``sim`` (the hardware emulator in-process), ``serial`` (pyserial + the framed protocol), ``can``
(python-can + the DBC), ``canopen`` (a CiA 402 drive via the canopen library, acceleration from
raw CAN frames), ``nidaqmx`` (an NI DAQ IEPE channel; optional extra). Modules are imported only
when chosen, so a missing optional package matters only to the backend that needs it.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from typing import Any

from wearbench.acquisition.drivers import Rig
from wearbench.bench.schema import BACKENDS, Bench
from wearbench.hardware.protocol.messages import FaultCode

__all__ = ["fault_name", "open_rig"]


def fault_name(code: int) -> str | None:
    """Lower-case name of a protocol fault code (serial and CAN share them), None for no fault."""
    if not code:
        return None
    try:
        return FaultCode(code).name.lower()
    except ValueError:
        return f"fault 0x{code:02x}"


def open_rig(bench: Bench, backend: str | None = None, options: Mapping[str, Any] | None = None) -> Rig:
    """Open the drive and sources of ``backend`` (default: the bench file's ``[hardware] backend``).

    ``options`` override the bench file's ``[hardware.<backend>]`` table.
    """
    name = backend or bench.hardware.backend
    if name not in BACKENDS:
        raise ValueError(f"backend {name!r}: expected one of {sorted(BACKENDS)}")
    module = importlib.import_module(f"wearbench.acquisition.backends.{name}")
    return module.open_rig(bench, {**bench.hardware.options.get(name, {}), **(options or {})})
