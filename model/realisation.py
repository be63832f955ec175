"""Realisations of a bench: the nominal model made to differ as a built bench differs from its file.

A realisation draws every quantity of the bench's ``[tolerances]`` (masses, inertias, body points,
ground points, friction, restitution, contact exponent, true motor speed and its ripple) from a
seed, starts the journals with a random velocity inside their clearances, lets the transient
settle and keeps what follows. Theory ensembles (``wearbench.validation.ensemble``) and the
non-twin bench emulator (``wearbench.hardware.emulators``) both draw from here, so a truth and a
candidate theory differ only by their seeds. Imports the bench schema and the model.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd
from wearbench.bench.schema import Bench, ContactLaw, Tolerances, WearState
from wearbench.model.scene import Scene, build_scene
from wearbench.model.simulation import SimulationResult, simulate
from wearbench.model.surfaces import JointSurfaces

__all__ = ["Realisation", "RealisationRun", "draw_realisation", "realisation_start", "simulate_state", "state_scene"]

_CUT = 3.0  # draws are cut at this many standard deviations


@dataclass(frozen=True)
class Realisation:
    """One draw of a bench within its tolerances (``seed`` None: the nominal bench, no draw)."""

    seed: int | None
    bench: Bench
    speed_scale: float = 1.0   # true motor speed / commanded
    ripple: float = 0.0        # relative amplitude of the once-per-revolution speed ripple
    ripple_phase: float = 0.0  # rad
    start: float = 0.0         # journal start-velocity spread (clearances per radian of crank)

    def describe(self) -> dict[str, float | int | None]:
        return {"seed": self.seed, "speed_scale": self.speed_scale, "ripple": self.ripple,
                "ripple_phase": self.ripple_phase, "start": self.start}


@dataclass(frozen=True)
class RealisationRun:
    """What follows the settled transient of one realisation, on the simulation's output grid."""

    realisation: Realisation
    t: np.ndarray            # s, from the end of the settling revolutions
    motor_angle: np.ndarray  # rad, unwrapped, signed (ratio 1 driver frame: crank angle / ratio)
    crank: np.ndarray        # rad, unwrapped angle of the encoder joint
    acc: np.ndarray          # m/s^2, slider acceleration along the sensor axis
    joint: str               # the encoder joint
    summary: dict
    table: pd.DataFrame | None = None  # the simulation's table over the same rows (t as above)


def _normal(rng: np.random.Generator, size=None) -> np.ndarray | float:
    return np.clip(rng.standard_normal(size), -_CUT, _CUT)


def draw_realisation(bench: Bench, seed: int | None, tolerances: Tolerances | None = None) -> Realisation:
    """The bench as built, drawn with ``seed`` from ``tolerances`` (default the bench's own)."""
    if seed is None:
        return Realisation(None, bench)
    tol = bench.tolerances if tolerances is None else tolerances
    rng = np.random.default_rng([int(seed), 0x5EED])
    bodies = []
    for b in bench.bodies:
        mass = b.mass * (1.0 + tol.mass * _normal(rng))
        inertia = b.inertia * (1.0 + tol.inertia * _normal(rng))
        points = {name: (x + tol.length * _normal(rng), y + tol.length * _normal(rng))
                  for name, (x, y) in b.points.items()}
        bodies.append(replace(b, mass=float(mass), inertia=float(inertia), points=points))
    ground = {name: (x + tol.ground * _normal(rng), y + tol.ground * _normal(rng))
              for name, (x, y) in bench.ground_points.items()}

    def contact(c: ContactLaw) -> ContactLaw:
        return replace(c, friction_coefficient=max(0.0, c.friction_coefficient * (1 + tol.friction * _normal(rng))),
                       restitution=float(np.clip(c.restitution + tol.restitution * _normal(rng), 0.7, 0.99)),
                       exponent=float(np.clip(c.exponent + tol.exponent * _normal(rng), 1.0, 2.0)))

    joints = tuple(replace(j, clearance=replace(j.clearance, contact=contact(j.clearance.contact)))
                   if j.clearance is not None else j for j in bench.joints)
    built = replace(bench, bodies=tuple(bodies), ground_points=ground, joints=joints)
    return Realisation(int(seed), built, speed_scale=float(1.0 + tol.speed * _normal(rng)),
                       ripple=float(abs(tol.ripple * _normal(rng))), ripple_phase=float(rng.uniform(0, 2 * math.pi)),
                       start=tol.start)


def state_scene(bench: Bench, state: WearState | None = None,
                surfaces: Mapping[str, JointSurfaces] | None = None) -> Scene:
    """The scene of ``bench`` in candidate ``state`` (its clearances and worn surfaces); ``surfaces``:
    worn surfaces in memory instead of the state's files."""
    if state is None and surfaces is None:
        return build_scene(bench)
    if surfaces is None and state.surfaces:
        surfaces = {j: JointSurfaces.load(p) for j, p in state.surfaces.items()}
    clearances = dict(state.clearances) or None if state is not None else None
    return build_scene(bench, clearances=clearances, surfaces=surfaces or None)


def _start_velocity(scene: Scene, speed: float, spread: float, rng: np.random.Generator) -> np.ndarray:
    """Nominal velocities plus a random kick that the constraint projection at t = 0 turns into a
    random journal velocity inside the clearances (ideal joints remove the rest)."""
    v = scene.v_unit * speed
    if spread <= 0 or not scene.clearance_joints:
        return v
    c = min(scene.clearance_params(j)["bearing_radius"] - scene.clearance_params(j)["journal_radius"]
            for j in scene.clearance_joints)
    sigma = spread * c * abs(speed)  # m/s
    scale = np.tile([1.0, 1.0, 1.0 / 0.1], scene.n // 3)
    return v + sigma * scale * _normal(rng, scene.n)


def realisation_start(real: Realisation, scene: Scene, speed: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The start state (q, v) at t = 0 of realisation ``real`` in ``scene`` at motor ``speed`` (rad/s):
    the assembled positions and a random journal velocity inside the clearances drawn from the
    realisation's seed; None for the nominal bench (the model's own start)."""
    if real.seed is None:
        return None
    rng = np.random.default_rng([int(real.seed), 0x57A7])
    return scene.q0.copy(), _start_velocity(scene, speed, real.start, rng)


def simulate_state(bench: Bench, state: WearState | None, seed: int | None, *, revolutions: float,
                   settle: float = 2.0, speed: float | None = None, output_rate: float | None = None,
                   tolerances: Tolerances | None = None, surfaces: Mapping[str, JointSurfaces] | None = None,
                   **options) -> RealisationRun:
    """Simulate ``settle`` + ``revolutions`` motor revolutions of one realisation of ``bench`` in
    ``state`` and keep the last ``revolutions``.

    seed: None for the nominal bench started as the model starts (journals centred, ideal
    velocities); otherwise the draw of :func:`draw_realisation`. speed: commanded motor speed
    (rad/s, default the bench's); the realisation turns at ``speed_scale`` times it with its ripple.
    surfaces: worn surfaces in memory instead of the state's files.
    options: passed to :func:`wearbench.model.simulation` (method, rtol, ...).
    """
    real = draw_realisation(bench, seed, tolerances)
    commanded = bench.speed if speed is None else float(speed)
    if commanded == 0:
        raise ValueError("simulate_state: a realisation needs a turning motor (speed 0 rad/s)")
    if not revolutions > 0 or settle < 0:
        raise ValueError(f"simulate_state: revolutions = {revolutions}, settle = {settle}: expected "
                         "revolutions > 0 and settle >= 0")
    true_speed = commanded * real.speed_scale
    scene = state_scene(real.bench.with_speed(true_speed), state, surfaces)
    t_end = (settle + revolutions) * 2 * math.pi / abs(true_speed)
    profile = None
    if real.ripple:
        w, r, phi = true_speed, real.ripple, real.ripple_phase
        profile = (lambda t: w * (1.0 + r * np.sin(abs(w) * t + phi)))
    initial = realisation_start(real, scene, float(profile(0.0)) if profile else true_speed)
    result: SimulationResult = simulate(scene, t_end=t_end, speed=true_speed if profile is None else profile,
                                        output_rate=output_rate, initial=initial, **options)
    table = result.table
    driver = bench.encoder_driver
    t = table["t"].to_numpy()
    crank = table[f"theta_{driver.joint}"].to_numpy()
    motor = (crank - driver.phase) / driver.ratio
    keep = t >= t_end * settle / (settle + revolutions) - 1e-12
    kept = table[keep].reset_index(drop=True)
    kept["t"] = t[keep] - t[keep][0]
    return RealisationRun(real, t[keep] - t[keep][0], motor[keep], crank[keep],
                          table["slider_acc"].to_numpy()[keep], driver.joint, result.summary, kept)

