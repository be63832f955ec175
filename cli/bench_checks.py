"""Checks of a bench file that cost more than reading it: what ``wearbench bench check`` adds to the loader.

The loader (``wearbench.bench.load``) checks every key and value of the file itself, for every command,
in milliseconds. What needs the model or the emulator is checked here, before any simulation:

- :func:`sweep_turns`: a kinematic sweep (clearance joints as ideal pins, the model's own constraints and
  Newton projection) shows the driven crank(s) turn full revolutions, with the pose the mechanism
  returns to; a crank that locks (a four-bar violating Grashof) or a mechanism that flips its assembly
  at a dead centre is refused naming the driver. The sweep also gives the accelerometer's point's
  acceleration along its axis from the motion alone (no impacts), which a range below it clips every
  cycle: refused naming the sensor's range.
- :func:`check_emulator`: the ``[emulator]`` table validated as the emulator reads it (its truth names a
  declared ``[[state]]``, every key known).
- the analysis at the bench's speed (``validation.measurement.scaling``): its bands, low-passes and
  the speeds it is validated for, refused when no impact band fits below what the sensor chain passes.

Each refusal is one :class:`~wearbench.bench.schema.BenchError` naming the file, key, value and what was
expected. Imports the bench, the model's scene and kernel, the emulator's configuration and the analysis's
scaling.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from wearbench.bench.schema import GROUND, Bench, BenchError

__all__ = ["Sweep", "check_bench", "check_emulator", "sweep_turns"]

G = 9.80665  # m/s^2 per g
_STEP = math.radians(1.0)  # grid step of the fastest driver's crank
_MIN_STEP = 1e-7  # rad of motor angle: below this the crank is taken as locked
_MAX_POSES = 20000
_TOL = 1e-10  # m, rad: the model's assembly tolerance


@dataclass(frozen=True)
class Sweep:
    """A kinematic sweep over the motion's period: ``motor_span`` rad of motor angle in ``poses`` grid
    poses; ``sensor_peak``: the largest |acceleration| (m/s^2) of the accelerometer's point along its
    axis at the bench's speed from the motion alone (ideal joints; None without an accelerometer)."""

    motor_span: float
    poses: int
    sensor_peak: float | None

    def describe(self, bench: Bench) -> str:
        cranks = [d.joint for d in bench.drivers if d.ratio]
        text = (f"crank{'s' if len(cranks) > 1 else ''} {', '.join(cranks)} turn{'' if len(cranks) > 1 else 's'} "
                f"full revolutions (kinematic sweep of {self.poses} poses)")
        if self.sensor_peak is not None:
            acc = bench.sensor("accelerometer")
            text += (f"; {acc.name}: {self.sensor_peak / G:.3g} g from the motion alone at "
                     f"{bench.speed:.4g} rad/s, {100 * self.sensor_peak / acc.range:.2g} % of its {acc.range / G:.4g} g "
                     "range (impacts add to it)")
        return text


def _driver_key(bench: Bench) -> tuple[str, object]:
    if len(bench.drivers) == 1:
        return "driver[0].joint", bench.drivers[0].joint
    return "driver", [d.joint for d in bench.drivers]


def _wrap(dq: np.ndarray) -> np.ndarray:
    """Differences of absolute coordinates with each angle taken modulo 2 pi."""
    out = dq.copy()
    out[2::3] = (out[2::3] + math.pi) % (2 * math.pi) - math.pi
    return out


def sweep_turns(bench: Bench, *, check_range: bool = True) -> Sweep | None:
    """Turn the motor through the motion's period with every joint ideal and check each pose closes.

    The period: until the slowest driver has turned one revolution (all of them a whole number of
    revolutions when their ratios allow; then the mechanism must be back at its start). Steps of 1 deg
    of the fastest crank, each a predictor along the velocity and the model's Newton projection
    (``kernel.project``), halved where the projection fails or moves the pose far from the prediction.
    Returns None when the ideal mechanism is not fully driven (its motion is not kinematics alone).
    Raises BenchError naming the driver when the cranks lock or the assembly flips, and (with
    ``check_range``) naming the accelerometer's range when the motion alone exceeds it.
    """
    from wearbench.model import build_scene
    from wearbench.model import kernel as K

    scene = build_scene(bench, clearances={j.name: None for j in bench.clearance_joints})
    ratios = [abs(d.ratio) for d in bench.drivers if d.ratio]
    if scene.dof != 0 or not ratios:
        return None
    P, W = scene.params, scene.work()
    sign = 1.0 if bench.speed >= 0 else -1.0  # kinematics is the same either way; sweep as the motor turns
    span = 2 * math.pi / min(ratios)
    n = min(_MAX_POSES, math.ceil(span / (_STEP / max(ratios))))
    grid = span / n
    q, v = scene.q0.copy(), scene.v_unit * sign
    poses = [q.copy()]
    t = 0.0
    for i in range(1, n + 1):
        target = i * grid
        while t < target - 1e-12:
            h = target - t
            while True:
                pred = q + v * h
                qn, vn = pred.copy(), v.copy()
                status = K.project(t + h, qn, vn, sign, P, W, _TOL, 30)
                if status == K.OK and np.max(np.abs(qn - pred)) <= 0.2 * np.max(np.abs(v * h)) + 1e-12:
                    break
                h /= 2
                if h < _MIN_STEP:
                    _locked(bench, t, sign)
            q, v, t = qn, vn, t + h
        poses.append(q.copy())
    whole = all(abs(r / min(ratios) - round(r / min(ratios))) < 1e-9 for r in ratios)
    if whole and np.max(np.abs(_wrap(poses[-1] - poses[0]))) > 1e-6:
        key, value = _driver_key(bench)
        raise BenchError(bench.path or bench.name, key, value,
                         "expected the mechanism back at its start after the cranks' full revolutions: it comes "
                         "back in another assembly (it passes a dead centre, where the links line up and the "
                         "assembly can flip); check lengths, ground points and [assembly]")
    peak = _sensor_peak(bench, scene, np.array(poses), grid, periodic=whole)
    if peak is not None and check_range:
        i, acc = next((i, s) for i, s in enumerate(bench.sensors) if s.kind == "accelerometer")
        if peak > acc.range:
            raise BenchError(bench.path or bench.name, f"sensor[{i}] ({acc.name}).range", f"{acc.range / G:.4g} g",
                             f"expected a range above the {peak / G:.3g} g its point reaches along its axis at the "
                             f"bench's speed {bench.speed:.4g} rad/s from the motion alone (kinematic sweep, ideal "
                             "joints; impacts in clearance joints add to it): it would clip every cycle")
    return Sweep(span, n, peak)


def _locked(bench: Bench, t: float, sign: float) -> None:
    """BenchError: the cranks cannot turn past motor angle ``t`` (rad from the start)."""
    cranks = ", ".join(f"{d.joint} at {math.degrees(d.phase + d.ratio * sign * t):.1f} deg" for d in bench.drivers)
    key, value = _driver_key(bench)
    raise BenchError(bench.path or bench.name, key, value,
                     f"expected cranks that turn full revolutions: the mechanism (clearance joints as ideal pins) "
                     f"cannot turn past {math.degrees(t):.1f} deg of motor turn after its start ({cranks}): its "
                     "loop no longer closes there, or only through a dead centre where links line up (a four-bar's "
                     "crank turns fully, clear of dead centres, when its shortest plus longest link are shorter "
                     "than the other two, Grashof); check lengths and ground points")


def _sensor_peak(bench: Bench, scene, poses: np.ndarray, grid: float, *, periodic: bool) -> float | None:
    """Largest |acceleration| (m/s^2) along the accelerometer's axis at the bench's speed, from second
    differences of its point over the sweep's grid (motor angle step ``grid``)."""
    acc = next((s for s in bench.sensors if s.kind == "accelerometer"), None)
    if acc is None or acc.body == GROUND:
        return None
    b = scene.body_index(acc.body)
    sx, sy = bench.body(acc.body).points[acc.point]
    x, y, th = poses[:, 3 * b], poses[:, 3 * b + 1], poses[:, 3 * b + 2]
    c, s = np.cos(th), np.sin(th)
    p = np.stack([x + c * sx - s * sy, y + s * sx + c * sy], axis=1)
    u = np.stack([np.cos(th + acc.axis), np.sin(th + acc.axis)], axis=1)
    if periodic:
        p, u = p[:-1], u[:-1]
        d2 = (np.roll(p, -1, 0) - 2 * p + np.roll(p, 1, 0)) / grid**2
    else:
        d2 = np.zeros_like(p)
        d2[1:-1] = (p[2:] - 2 * p[1:-1] + p[:-2]) / grid**2
    return float(np.max(np.abs(np.sum(d2 * u, axis=1)))) * bench.speed**2


def check_emulator(bench: Bench):
    """The bench's ``[emulator]`` table as the emulator reads it (BenchError naming file, key and value)."""
    from wearbench.hardware.emulators.config import EmulatorConfig

    return EmulatorConfig.from_bench(bench)


def check_bench(bench: Bench) -> list[str]:
    """Every check beyond loading; what each found, as notes for the ``ok`` line (BenchError on a refusal)."""
    from wearbench.validation.measurement.scaling import resolve_analysis

    notes = []
    sweep = sweep_turns(bench)
    notes.append(sweep.describe(bench) if sweep is not None else
                 "not fully driven with its clearance joints ideal: no kinematic sweep")
    check_emulator(bench)
    if bench.clearance_joints and any(s.kind == "accelerometer" for s in bench.sensors):
        notes.extend(resolve_analysis(bench).describe())  # refused when no impact band fits the sensor chain
    return notes
