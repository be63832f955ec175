"""`simulate`: run a scene and return a tidy results table, a summary and (optionally) contact records.

Holds :func:`simulate`, :class:`SimulationResult` (with Poincare sections and phase portraits) and
:class:`SimulationError`. It chooses kinematics + inverse dynamics for a fully driven ideal scene
and time integration otherwise (``integrators.py``). Imports numpy, pandas and the model's scene,
kernel and integrators; it must not import plots or the CLI.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from wearbench.model import integrators as I
from wearbench.model import kernel as K
from wearbench.model.contact import impact_speed
from wearbench.model.methods import DRIFT_TOLERANCE, Method, get_method
from wearbench.model.scene import Scene, dense_jacobian

__all__ = ["CONTACT_COLUMNS", "DEFAULT_OUTPUT_RATE", "DRIFT_TOLERANCE", "STEPS_PER_CALL", "SimulationError",
           "SimulationResult", "error_scales", "simulate", "step_cap"]

DEFAULT_OUTPUT_RATE = 20_000.0  # samples/s of the table (20 points per ms)
_PROJECTION_TOL = 1e-11  # m
_STILL_STEP_CAP = 1e-3  # s, largest adaptive step when the motor does not turn
_BLOW_UP = 0.05  # penetration above this fraction of the journal radius is a blow-up
_MAX_STEPS = 50_000_000  # accepted steps before a run gives up
STEPS_PER_CALL = 2_000  # accepted steps per call of the compiled loop (~0.1 s, worn surfaces ~1 s): Ctrl-C acts between
CONTACT_COLUMNS = ("t", "dt", "fn", "vt", "omega_rel", "phi_bearing", "phi_journal", "pen")


class SimulationError(RuntimeError):
    """Numerical failure: names the time (s), the joint or coordinate, the quantity and the state."""

    def __init__(self, message: str, *, t: float, joint: str | None = None, quantity: str = "",
                 state: dict | None = None):
        self.t, self.joint, self.quantity, self.state = t, joint, quantity, state or {}
        super().__init__(message)


@dataclass
class SimulationResult:
    """What :func:`simulate` returns: the table (one row per output time), the summary and, with
    ``record_contacts=True``, one contact DataFrame per clearance joint (one row per accepted step)."""

    table: pd.DataFrame
    summary: dict
    contacts: dict[str, pd.DataFrame] | None = None
    scene: Scene | None = field(default=None, repr=False)
    final: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False)  # (q, v) at t_end

    def poincare(self, columns: tuple[str, str] = ("slider_pos", "slider_vel"), driver: str | None = None
                 ) -> pd.DataFrame:
        """Poincare section: ``columns`` sampled once per crank revolution (stroboscopic map).

        The section is taken where the crank angle of ``driver`` (default: the first driver) has
        advanced by a whole number of revolutions since t = 0, by linear interpolation in the table.
        Columns: revolution, t, and the two requested columns.
        """
        col = f"theta_{driver or self.scene.drivers[0][0]}" if self.scene and self.scene.drivers else None
        if col is None or col not in self.table:
            raise ValueError("a Poincare section needs a driven crank (theta_<joint> column)")
        theta = self.table[col].to_numpy()
        rev = (theta - theta[0]) / (2 * math.pi)
        rev = np.abs(rev)
        marks = np.arange(1, int(np.floor(rev[-1] + 1e-9)) + 1)
        t = np.interp(marks, rev, self.table["t"].to_numpy())
        out = {"revolution": marks, "t": t}
        for c in columns:
            out[c] = np.interp(t, self.table["t"].to_numpy(), self.table[c].to_numpy())
        return pd.DataFrame(out)

    def phase(self, joint: str) -> pd.DataFrame:
        """Phase portrait of a clearance joint: eccentricity components and their rates (m, m/s)."""
        t = self.table["t"].to_numpy()
        ex = self.table[f"{joint}_ex"].to_numpy()
        ey = self.table[f"{joint}_ey"].to_numpy()
        return pd.DataFrame({"t": t, "ex": ex, "ey": ey, "vx": np.gradient(ex, t), "vy": np.gradient(ey, t)})


def _output_times(t_end: float, rate: float) -> np.ndarray:
    count = math.floor(t_end * rate + 1e-9) + 1
    times = np.arange(count) / rate
    if times[-1] < t_end - 1e-12:
        times = np.append(times, t_end)
    return times


def _recorded_columns(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """The entries of the state y = (q, v) and of the accelerations the table reads (``Output.ycols``,
    ``Output.acols``): the drivers' angles and the sensor body's position, velocity and acceleration."""
    n = scene.n
    ycols = {3 * b + 2 for _, b in scene.drivers}
    acols: set[int] = set()
    if scene.sensor is not None:
        body = 3 * scene.sensor[0]
        acols = {body, body + 1, body + 2}
        ycols |= acols | {n + c for c in acols}
    return np.array(sorted(ycols), dtype=np.int64), np.array(sorted(acols), dtype=np.int64)


def _table(scene: Scene, out: I.Output) -> pd.DataFrame:
    n = scene.n
    y = {c: out.y[:, j] for j, c in enumerate(out.ycols)}  # the recorded entries of the state, by index
    a = {c: out.a[:, j] for j, c in enumerate(out.acols)}
    cols: dict[str, np.ndarray] = {"t": out.t}
    for joint, b in scene.drivers:
        cols[f"theta_{joint}"] = y[3 * b + 2]
    if scene.sensor is not None:
        b, (sx, sy), axis = scene.sensor
        body = [np.ascontiguousarray(x[first + 3 * b + i]) for x, first in ((y, 0), (y, n), (a, 0)) for i in range(3)]
        cols["slider_pos"], cols["slider_vel"], cols["slider_acc"] = K.point_along(*body, float(sx), float(sy),
                                                                                   float(axis))
    else:
        for name in ("slider_pos", "slider_vel", "slider_acc"):
            cols[name] = np.full(out.t.size, np.nan)
    for k, joint in enumerate(scene.clearance_joints):
        for name, idx in (("ex", K.CO_EX), ("ey", K.CO_EY), ("pen", K.CO_PEN), ("fn", K.CO_FN),
                          ("ft", K.CO_FT), ("vn", K.CO_VN), ("vt", K.CO_VT)):
            cols[f"{joint}_{name}"] = out.c[:, k, idx]
    for prefix, row in scene.reaction_rows:  # force on the pin's second body from the first (N)
        cols[f"{prefix}_fx"] = out.lam[:, row]
        cols[f"{prefix}_fy"] = out.lam[:, row + 1]
    return pd.DataFrame(cols)


def _state(scene: Scene, y: np.ndarray, cout: np.ndarray) -> dict:
    n = scene.n
    state = {"q": {b: tuple(float(x) for x in y[3 * i: 3 * i + 3]) for i, b in enumerate(scene.bodies)},
             "v": {b: tuple(float(x) for x in y[n + 3 * i: n + 3 * i + 3]) for i, b in enumerate(scene.bodies)}}
    for k, j in enumerate(scene.clearance_joints):
        state[j] = {"ex": float(cout[k, K.CO_EX]), "ey": float(cout[k, K.CO_EY]),
                    "pen": float(cout[k, K.CO_PEN]), "fn": float(cout[k, K.CO_FN])}
    return state


def _singular_joints(scene: Scene, t: float, y: np.ndarray, speed: float) -> str:
    """Joints whose constraint rows are (nearly) dependent at the state: from the left singular
    vector of the smallest singular value of Phi_q."""
    m, n = scene.m, scene.n
    W = scene.work()
    K.constraints(t, y[:n].copy(), y[n:].copy(), speed, scene.params, W)
    u, _, _ = np.linalg.svd(dense_jacobian(scene.params, W.Jv, n))
    weights = np.abs(u[:, -1]) if m else np.zeros(0)
    names = []
    for k in np.argsort(-weights):
        if weights[k] > 0.2 and scene.row_joints[k] not in names:
            names.append(scene.row_joints[k])
    return ", ".join(names) or "?"


def _fail(scene: Scene, status: int, stats: np.ndarray, y: np.ndarray, cout: np.ndarray, speed: float,
          method: str, drift_tol: float) -> SimulationError:
    t = float(stats[0]["t"])
    state = _state(scene, y, cout)
    where = f"at t = {t:.6g} s ({method})"
    if status == I.SINGULAR or status == I.NO_PROJECTION:
        joints = _singular_joints(scene, t, y, speed)
        what = ("singular constraint Jacobian" if status == I.SINGULAR
                else "the constraints cannot be satisfied (position analysis / projection does not converge)")
        return SimulationError(f"{what} {where}: the mechanism reaches a singular pose at joint(s) {joints}",
                               t=t, joint=joints, quantity="constraint Jacobian", state=state)
    if status == I.NOT_FINITE:
        i = int(stats[0]["detail"])
        n = scene.n
        kind = "velocity" if i >= n else "coordinate"
        body, comp = scene.bodies[(i % n) // 3], ["x", "y", "theta"][(i % n) % 3]
        return SimulationError(f"non-finite {kind} {comp} of body {body} {where} (value {stats[0]['value']})",
                               t=t, joint=body, quantity=f"{kind} {comp}", state=state)
    if status == I.STEP_COLLAPSE:
        k = int(np.argmax(cout[:, K.CO_FN])) if cout.shape[0] else -1
        joint = scene.clearance_joints[k] if k >= 0 else None
        extra = f"; largest contact force at joint {joint}: {cout[k, K.CO_FN]:.4g} N" if joint else ""
        return SimulationError(f"step size collapsed to {stats[0]['h']:.3g} s {where}{extra}", t=t, joint=joint,
                               quantity="step size", state=state)
    if status == I.DRIFT:
        W = scene.work()
        n = scene.n
        K.constraints(t, y[:n].copy(), y[n:].copy(), speed, scene.params, W)
        joint = scene.row_joints[int(np.argmax(np.abs(W.phi)))]
        return SimulationError(f"constraint drift {stats[0]['value']:.3g} (m or rad) exceeds {drift_tol:g} "
                               f"{where} at joint {joint}", t=t, joint=joint, quantity="constraint drift",
                               state=state)
    if status == I.BLOW_UP:
        joint = scene.clearance_joints[int(stats[0]["detail"])]
        return SimulationError(f"penetration {stats[0]['value']:.4g} m at joint {joint} {where} exceeds "
                               f"{_BLOW_UP:.0%} of the journal radius: the contact blew up (step too large for "
                               "the contact stiffness) or the mechanism jams", t=t, joint=joint,
                               quantity="penetration", state=state)
    if status == I.TOO_MANY_STEPS:
        return SimulationError(f"too many steps {where}", t=t, quantity="steps", state=state)
    return SimulationError(f"integration failed with status {status} {where}", t=t, state=state)


def _profile(profile, t_end: float) -> np.ndarray:
    """Rows (time, motor angle, speed) of a speed profile, the angle integrated exactly (trapezoid)."""
    if callable(profile):
        count = max(2, math.ceil(t_end / 1e-4) + 2)  # one sample past t_end: no end effect
        times = np.arange(count) * 1e-4  # a fixed grid: the same profile samples for any t_end
        speeds = np.asarray(profile(times), dtype=float) * np.ones_like(times)
    else:
        times, speeds = (np.asarray(x, dtype=float) for x in profile)
    if times.ndim != 1 or times.shape != speeds.shape or times.size < 1 or times[0] != 0.0:
        raise ValueError("speed profile: expected arrays (times, speeds) of equal length starting at t = 0")
    if np.any(np.diff(times) <= 0) or not np.isfinite(speeds).all():
        raise ValueError("speed profile: times must increase strictly and speeds be finite")
    angles = np.concatenate([[0.0], np.cumsum(0.5 * (speeds[1:] + speeds[:-1]) * np.diff(times))])
    return np.column_stack([times, angles, speeds])


def step_cap(scene: Scene, speed: float, profiled: bool) -> float:
    """Largest step of an adaptive method (s): 1/100 of a motor revolution at the run's speed (with a
    speed profile: the faster of its initial speed and the bench's), 1 ms for a still motor. It
    depends on the scene and speed only, never on the duration asked for, so a run's first
    revolution is the same however long the run."""
    top = max(abs(speed), abs(scene.bench.speed)) if profiled else abs(speed)
    return 2 * math.pi / top / 100.0 if top > 0 else _STILL_STEP_CAP


def error_scales(scene: Scene, atol: float | tuple[float, float]) -> np.ndarray:
    """Absolute error scale per state component (positions, then velocities) of an adaptive method.

    A number: atol (m) on positions, atol / 0.1 m on angles, and the same times a contact frequency
    scale (1e3 /s) on velocities. A pair (position m, velocity m/s): absolute scales per kind of
    component, position on positions, position / 0.1 m on angles, velocity on velocities and
    velocity / 0.1 m on angular velocities (a shape one number cannot express; with rtol 0 the
    scales alone control the step)."""
    bodies = scene.n // 3
    if isinstance(atol, (tuple, list)):
        position, velocity = (float(x) for x in atol)
        return np.concatenate([np.tile([position, position, position / 0.1], bodies),
                               np.tile([velocity, velocity, velocity / 0.1], bodies)])
    atol = float(atol)
    base = np.tile([atol, atol, atol / 0.1], bodies)
    return np.concatenate([base, base * 1e3])


def _duration(scene: Scene, speed, t_end: float | None, revolutions: float):
    """(motor speed, t_end, profile): the constant speed (rad/s; 0 for a profile) and the run's duration
    (s), and the speed profile or None."""
    profile = speed if callable(speed) or isinstance(speed, (tuple, list)) else None
    if profile is not None:
        if t_end is None:
            raise ValueError("a speed profile needs t_end (s): revolutions are not defined for a varying speed")
        speed = 0.0
    else:
        speed = scene.bench.speed if speed is None else float(speed)
    if t_end is None:
        if speed == 0:
            raise ValueError("t_end is needed when the motor speed is 0 (revolutions are undefined)")
        t_end = revolutions * 2 * math.pi / abs(speed)
    if not t_end > 0:
        raise ValueError(f"t_end = {t_end}: expected a positive duration (s)")
    return speed, t_end, profile


def _output(scene: Scene, times: np.ndarray, record_contacts: bool, evaluate_samples: bool) -> I.Output:
    """The arrays the loop fills (zeros), one row per output time (of the state and the accelerations only
    the entries the table reads); a contact record buffer when recording."""
    m, nc = scene.m, len(scene.clearance_joints)
    ycols, acols = _recorded_columns(scene)
    return I.Output(t=times, y=np.zeros((times.size, ycols.size)), a=np.zeros((times.size, acols.size)),
                    c=np.zeros((times.size, nc, K.NCO)), lam=np.zeros((times.size, m)),
                    rec=np.zeros((4096 if record_contacts else 1, nc, I.NREC)), record=record_contacts,
                    evaluate=evaluate_samples, ycols=ycols, acols=acols)


def _kinematics(scene: Scene, P, speed: float, q: np.ndarray, v: np.ndarray, out: I.Output, wall0: float
                ) -> SimulationResult:
    """Kinematics + inverse dynamics at the output times (a fully driven scene with ideal joints)."""
    if scene.dof != 0 or scene.clearance_joints:
        raise ValueError(f"method 'kinematics' needs a fully driven scene with ideal joints; this one "
                         f"has {scene.dof} DOF ({scene.description})")
    stats = I.new_stats()
    status = I.kinematics_loop(out, q, v, speed, P, scene.work(), _PROJECTION_TOL, stats)
    if status != 0:
        code = I.SINGULAR if status == K.SINGULAR else I.NO_PROJECTION
        raise _fail(scene, code, stats, np.concatenate([q, v]), np.zeros((0, K.NCO)), speed, "kinematics",
                    DRIFT_TOLERANCE)
    contacts = {} if out.record else None
    table = _table(scene, out)
    return SimulationResult(table, _summary(scene, "kinematics", stats, table, wall0, speed), contacts, scene)


def _sensor(scene: Scene) -> np.ndarray:
    """The accelerometer as the loop reads it (see ``integrators.sensor_acc``): body -1 without one."""
    sensor = np.array([-1.0, 0.0, 0.0, 0.0])
    if scene.sensor is not None:
        b, (sx, sy), axis = scene.sensor
        sensor[:] = (b, sx, sy, axis)
    return sensor


def _start(scene: Scene, meth: Method, P, speed: float, y: np.ndarray, proj_tol: float):
    """The mechanism record (``kernel.Model``) at t = 0 and f there: the state projected onto the
    constraints (if the method projects), f(0, y) into k[0], the contact modes of the joints already in
    contact. Returns (mdl, k, cout)."""
    n, nc = scene.n, len(scene.clearance_joints)
    W = scene.work()
    if meth.project and K.project(0.0, y[:n], y[n:], speed, P, W, proj_tol, 20) != 0:
        raise SimulationError("the initial state does not satisfy the constraints (projection failed at "
                              "t = 0)", t=0.0, quantity="initial state")
    alpha, beta = meth.baumgarte
    mdl = K.Model(P=P, speed=speed, alpha=float(alpha), beta=float(beta), inc=np.zeros(nc, dtype=np.int64),
                  v0i=np.zeros(nc), W=W)
    k = np.zeros((meth.tableau.scheme().end + 1, 2 * n))
    cout = np.zeros((nc, K.NCO))
    if I.deriv(0.0, y, mdl, k[0], np.zeros(scene.m), cout) != 0:
        raise _fail(scene, I.SINGULAR, I.new_stats(), y, cout, speed, meth.name, meth.drift_tolerance)
    for c in range(nc):
        if cout[c, K.CO_PEN] > 0:
            mdl.inc[c] = 1
            mdl.v0i[c] = impact_speed(cout[c, K.CO_VN])
    return mdl, k, cout


def _integrate(scene: Scene, meth: Method, mdl: K.Model, y: np.ndarray, out: I.Output, tolerances: tuple,
               t_end: float, profiled: bool, start: tuple) -> tuple[I.Output, np.ndarray, I.Track]:
    """Run the compiled loop from t = 0 to t_end in calls of STEPS_PER_CALL steps (the contact record
    buffer doubled when full). ``tolerances``: (rtol, error scales, projection tolerance); ``start``: k and
    cout from :func:`_start`. Returns the output (its record buffer possibly grown), the statistics and
    the peak tracker; raises SimulationError on failure."""
    rtol, scales, proj_tol = tolerances
    k, cout = start
    scheme = meth.tableau.scheme()
    h = meth.step if meth.step is not None else 1e-6
    hmax = step_cap(scene, mdl.speed, profiled) if meth.adaptive else h
    blow = np.array([_BLOW_UP * scene.clearance_params(j)["journal_radius"] for j in scene.clearance_joints])
    control = I.Control(adaptive=meth.adaptive, project=meth.project, proj_tol=proj_tol,
                        drift_tol=meth.drift_tolerance, blow_pen=blow, atol=scales, rtol=rtol, hmin=1e-13, hmax=hmax,
                        max_steps=STEPS_PER_CALL)
    track = I.new_track(_sensor(scene), len(scene.clearance_joints), scheme, y.size)
    stats = I.new_stats()
    while True:
        status = I.run_loop(scheme, control, mdl, float(stats[0]["t"]), y, h, t_end, out, k, cout, stats, track)
        h = float(stats[0]["h"])
        if status == I.FULL:
            out = out._replace(rec=np.concatenate([out.rec, np.zeros_like(out.rec)]))
            continue
        if status == I.PAUSED:  # Python runs between calls: Ctrl-C acts within a call's time
            if stats[0]["steps"] < _MAX_STEPS:
                continue
            status = I.TOO_MANY_STEPS
        if status != I.DONE:
            raise _fail(scene, status, stats, y, cout, mdl.speed, meth.name, meth.drift_tolerance)
        return out, stats, track


def simulate(scene: Scene, *, revolutions: float = 3.0, t_end: float | None = None,
             method: str | Method = "default", rtol: float | None = None,
             atol: float | tuple[float, float] | None = None,
             speed: float | Callable[[np.ndarray], np.ndarray] | tuple[np.ndarray, np.ndarray] | None = None,
             output_rate: float | None = None, record_contacts: bool = False, step: float | None = None,
             initial: tuple[np.ndarray, np.ndarray] | None = None, evaluate_samples: bool = False
             ) -> SimulationResult:
    """Simulate ``scene`` from t = 0 (the bench's driver phases) to ``t_end``.

    revolutions: duration in motor revolutions when ``t_end`` (s) is None.
    method: "default" (kinematics + inverse dynamics for a fully driven ideal scene, else adaptive
    DOPRI5 with projection), a name registered in ``methods.METHODS`` ("kinematics", "dopri5", "accurate",
    "rk4-paper") or a :class:`Method` (which also sets the drift limit, ``Method.drift_tolerance``).
    rtol, atol: tolerances of an adaptive method (atol in m, or a pair (position m, velocity m/s) of
    absolute scales; see :func:`error_scales`).
    step: fixed step (s) of a fixed-step method (rk4-paper: 1e-4).
    speed: motor speed (rad/s), default the bench's; or a speed profile instead of a constant speed:
    a function speed(t) (rad/s, vectorised; sampled every 0.1 ms) or arrays (times s, speeds rad/s),
    linear in between, held after the last time; the drivers turn at ratio x the integrated motor
    angle. A profile needs ``t_end``.
    output_rate: table samples/s (default 20 kHz).
    initial: (q, v) at t = 0 instead of the assembled state (journals centred, ideal velocities).
    evaluate_samples: each table sample's accelerations and joint reactions from a full right-hand side
    at the interpolated state, as before issue 27 (slower); by default they come from the step's
    continuous extension (the derivative of the DOPRI5 dense output: the stages' values combined, no
    solve) and the contact columns from the force law at the interpolated state.
    Raises SimulationError on numerical failure (naming time, joint, quantity and state).
    """
    wall0 = time.perf_counter()
    speed, t_end, profile = _duration(scene, speed, t_end, revolutions)
    rate = DEFAULT_OUTPUT_RATE if output_rate is None else float(output_rate)
    if not rate > 0:
        raise ValueError(f"output_rate = {output_rate}: expected samples/s > 0")
    P = scene.params
    if profile is not None:
        P = P._replace(profile=_profile(profile, t_end))
        speed = float(P.profile[0, 2])
    q = scene.q0.copy() if initial is None else np.array(initial[0], dtype=float)
    v = scene.v_unit * speed if initial is None else np.array(initial[1], dtype=float)
    out = _output(scene, _output_times(t_end, rate), record_contacts, evaluate_samples)
    meth = get_method(method) if isinstance(method, str) else method
    name = method if isinstance(method, str) else method.name  # the alias "dopri5" never means kinematics
    if meth.tableau is None or (name == "default" and scene.dof == 0 and not scene.clearance_joints
                                and initial is None):
        return _kinematics(scene, P, speed, q, v, out, wall0)
    if step is not None:
        meth = dataclasses.replace(meth, step=float(step))
    atol_ = meth.atol if atol is None else atol
    positions = float(atol_[0] if isinstance(atol_, (tuple, list)) else atol_)
    # projection tolerance follows the integration tolerance (never looser than 1e-11 m)
    proj_tol = max(2e-15, min(_PROJECTION_TOL, 1e-2 * positions))
    y = np.concatenate([q, v])
    mdl, k, cout = _start(scene, meth, P, speed, y, proj_tol)
    tolerances = (meth.rtol if rtol is None else float(rtol), error_scales(scene, atol_), proj_tol)
    out, stats, track = _integrate(scene, meth, mdl, y, out, tolerances, t_end, profile is not None, (k, cout))
    return _result(scene, meth, mdl.speed, out, stats, track, y, wall0)


def _result(scene: Scene, meth: Method, speed: float, out: I.Output, stats: np.ndarray, track: I.Track,
            y: np.ndarray, wall0: float) -> SimulationResult:
    """The result of an integrated run: the table, the summary with the peaks from the dense output (the
    table's samples miss the tops of impacts by ~1 %), the contact records, the final state."""
    n, nc = scene.n, len(scene.clearance_joints)
    contacts = None
    if out.record:
        used = out.rec[: int(stats[0]["rec"])]
        contacts = {j: pd.DataFrame(used[:, c, :], columns=list(CONTACT_COLUMNS))
                    for c, j in enumerate(scene.clearance_joints)}
    table = _table(scene, out)
    summary = _summary(scene, meth.name, stats, table, wall0, speed)
    peaks = track.peaks
    summary["peak_fn"] = {j: float(peaks[c]) for c, j in enumerate(scene.clearance_joints)}
    if scene.sensor is not None and math.isfinite(summary["peak_slider_acc"]):
        summary["peak_slider_acc"] = float(peaks[nc])
    summary["peak_searches"] = int(stats[0]["peak_searches"])
    return SimulationResult(table, summary, contacts, scene, (y[:n].copy(), y[n:].copy()))


def _summary(scene: Scene, method: str, stats: np.ndarray, table: pd.DataFrame, wall0: float,
             speed: float) -> dict:
    acc = table["slider_acc"].to_numpy()
    return {
        "method": method,
        "wall_time_s": time.perf_counter() - wall0,
        "steps": int(stats[0]["steps"]),
        "rejected_steps": int(stats[0]["rejected"]),
        "function_evaluations": int(stats[0]["nfev"]),
        "peak_slider_acc": float(np.max(np.abs(acc))) if np.isfinite(acc).all() else float("nan"),
        "peak_fn": {j: float(table[f"{j}_fn"].max()) for j in scene.clearance_joints},
        "max_constraint_drift": float(stats[0]["drift_p"]),
        "max_velocity_drift": float(stats[0]["drift_v"]),
        "dof": scene.dof,
        "description": scene.description,
        "speed": speed,
        "t_end": float(table["t"].iloc[-1]),
    }
