"""A fault plan for an emulated bench: what goes wrong, and when, in a hardware-in-the-loop test.

:class:`FaultPlan` names the faults a lab's code meets on a real bench and turns them into the
emulator's ``[emulator.faults]`` and ``[emulator.accelerometer]`` keys (the emulators' own fault
machinery, :mod:`wearbench.hardware.emulators.config`). Times count from the first START_STREAM,
in seconds of device time; a value may also be a string with a unit (``"1.5 s"``, ``"40 ppm"``).
Imports the bench's units.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

from wearbench.bench.units import parse_quantity

__all__ = ["FaultPlan"]

_TIMES = {"drop_link_at": "disconnect_after", "garbage_at": "garbage_at", "stall_device_at": "freeze_at",
          "motor_fault_at": "stall_at", "lose_index_at": "index_lost_at", "bus_off_at": "bus_off_at"}


@dataclass(frozen=True)
class FaultPlan:
    """Faults an emulated bench injects (every field left at its default: a clean bench).

    - ``drop_link_at``: the link dies (serial: the pty closes; CAN: the device falls silent).
    - ``garbage_at`` / ``garbage_bytes``: a burst of random bytes on the line (CAN: frames of
      random bytes on the accelerometer's identifier).
    - ``stall_device_at``: the device's firmware hangs: no data, no replies, the link stays open.
    - ``motor_fault_at``: the motor stalls; the drive latches a fault (serial EVENT, CAN EMCY 0x7121).
    - ``lose_index_at``: the encoder's index pulse stops (a broken index line); counts go on.
    - ``clock_drift``: the accelerometer's sample clock runs fast by this fraction (``"40 ppm"`` or
      40e-6); blocks are still stamped at the nominal rate.
    - ``drop_rate``, ``corrupt_rate``: fractions of blocks lost and of frames with a flipped byte.
    - ``bus_off_at``: the CAN controller goes bus-off for 0.2 s (CAN only).
    """

    drop_link_at: float | str | None = None
    garbage_at: float | str | None = None
    garbage_bytes: int = 256
    stall_device_at: float | str | None = None
    motor_fault_at: float | str | None = None
    lose_index_at: float | str | None = None
    clock_drift: float | str = 0.0
    drop_rate: float = 0.0
    corrupt_rate: float = 0.0
    bus_off_at: float | str | None = None

    @property
    def clean(self) -> bool:
        """No fault planned."""
        return all(getattr(self, f.name) == f.default for f in fields(self))

    def first_fault(self) -> float | None:
        """Seconds into streaming of the first timed fault (None: no timed fault)."""
        times = [getattr(self, name) for name in _TIMES if getattr(self, name) is not None]
        return min((parse_quantity(t, "time") if isinstance(t, str) else float(t)) for t in times) if times else None

    def apply(self, table: dict[str, Any]) -> dict[str, Any]:
        """``table`` (a raw ``[emulator]`` table) with this plan's faults set in it (a new dict)."""
        out = {k: (dict(v) if isinstance(v, dict) else v) for k, v in table.items()}
        faults = dict(out.get("faults", {}))
        for name, key in _TIMES.items():
            value = getattr(self, name)
            if value is not None:
                faults[key] = value if isinstance(value, str) else f"{float(value)!r} s"
        if self.garbage_at is not None:
            faults["garbage_bytes"] = int(self.garbage_bytes)
        if self.drop_rate:
            faults["drop_rate"] = float(self.drop_rate)
        if self.corrupt_rate:
            faults["corrupt_rate"] = float(self.corrupt_rate)
        out["faults"] = faults
        if self.clock_drift:
            drift = self.clock_drift if isinstance(self.clock_drift, str) else f"{float(self.clock_drift) * 1e6!r} ppm"
            out["accelerometer"] = {**out.get("accelerometer", {}), "drift": drift}
        return out
