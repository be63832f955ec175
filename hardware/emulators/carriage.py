"""The slider carriage of a bench's accelerometer: which pins hold it and the lateral force they put
on it, read from the model's table (the cross-axis part of the sensor chain is driven by it).

On the model's ideal guide the carriage does not move sideways, so the force the rest of the
mechanism puts on it across the guide is exactly minus the guide's lateral reaction; the model writes
every ideal pin's reaction to its table (``<pin>_fx``, ``<pin>_fy``: force on a pin's later body from
its first), so no model change is needed. Imports numpy and the bench schema.
"""

from __future__ import annotations

import math

import numpy as np
from wearbench.bench.schema import GROUND, Bench

__all__ = ["carriage", "lateral_force"]


def carriage(bench: Bench) -> tuple[float, tuple[tuple[str, float], ...]] | None:
    """(lateral direction, rad; the reaction columns' prefixes with their signs) of the accelerometer's
    body, or None where the table cannot give its lateral force exactly. The body must slide on a
    prismatic guide fixed to the frame (its angle is then the guide's axis, so the sensor axis rotated
    +90 deg is the lateral direction) and be joined to the rest by ideal pins (their reactions are
    columns of the model's table: force on a pin's later body from its first)."""
    try:
        sensor = bench.sensor("accelerometer")
    except KeyError:
        return None
    body = sensor.body
    guides = [j for j in bench.joints if j.kind == "prismatic" and j.bodies == (GROUND, body)]
    others = [j for j in bench.joints if body in j.bodies and j not in guides]
    if len(guides) != 1 or any(j.kind != "revolute" or j.clearance is not None for j in others):
        return None
    pins: list[tuple[str, float]] = []
    for j in others:
        if len(j.bodies) == 2:
            pins.append((j.name, 1.0 if j.bodies[1] == body else -1.0))
        elif j.bodies[0] == body:  # a shared pin's reactions act on its later bodies from the first
            pins += [(f"{j.name}_{b}", -1.0) for b in j.bodies[1:]]
        else:
            pins.append((f"{j.name}_{body}", 1.0))
    return guides[0].axis + sensor.axis + 0.5 * math.pi, tuple(pins)


def lateral_force(bench: Bench, table) -> np.ndarray | None:
    """The force on the accelerometer's body along the lateral direction of :func:`carriage` from every
    pin it shares with the mechanism, plus its weight's component, over its mass (m/s^2), at each row
    of a simulation ``table`` of ``bench``; None where :func:`carriage` is None. With the body held on
    its ideal guide this is minus the guide's lateral reaction over the mass, exactly."""
    found = carriage(bench)
    if found is None:
        return None
    angle, pins = found
    ux, uy = math.cos(angle), math.sin(angle)
    body = bench.sensor("accelerometer").body
    mass = bench.body(body).mass
    f = np.full(len(table), mass * (bench.gravity[0] * ux + bench.gravity[1] * uy))
    for prefix, sign in pins:
        f += sign * (ux * table[f"{prefix}_fx"].to_numpy() + uy * table[f"{prefix}_fy"].to_numpy())
    return f / mass
