"""Scenes: a bench file's mechanism turned into the arrays the compiled kernel integrates.

Holds :class:`Scene`, :func:`build_scene` (absolute planar coordinates, ideal pins and prismatic
joints, drivers, gravity, clearance joints as force elements, worn surfaces, assembly at t = 0 by
Newton). The kernel's parameters are packed by ``packing.py``. Imports the bench dataclasses, the
surfaces contract and the model's own ``kernel`` and ``packing``; it must not import the
integrators, plots or CLI.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from wearbench.bench.schema import GROUND, Bench, BenchError
from wearbench.model import kernel as K
from wearbench.model.packing import Spring, Torque, pack_params
from wearbench.model.surfaces import JointSurfaces, surfaces_from_bench

__all__ = ["LOW_RESTITUTION", "Scene", "build_scene", "dense_jacobian"]

LOW_RESTITUTION = 0.7  # below this the Lankarani-Nikravesh law is not valid (it assumes ce near 1)
_ASSEMBLY_TOL = 1e-10  # m, rad


@dataclass
class Scene:
    """A mechanism ready to simulate. Build it with :func:`build_scene`.

    ``dof``: degrees of freedom with the drivers applied (0 = fully driven with ideal joints, solved
    by kinematics + inverse dynamics); each clearance joint adds 2. ``q0``, ``v0``: assembled state
    at t = 0 (journals centred in their bearings). ``description`` says what will be computed.
    """

    bench: Bench
    bodies: tuple[str, ...]
    clearance_joints: tuple[str, ...]
    dof: int
    description: str
    q0: np.ndarray
    v_unit: np.ndarray  # initial velocities per unit motor speed (rad/s)
    params: tuple  # the kernel's P tuple (see wearbench.model.kernel)
    reaction_rows: tuple[tuple[str, int], ...]  # (column prefix, first row) of each ideal pin pair
    row_joints: tuple[str, ...]  # joint name of each constraint row
    drivers: tuple[tuple[str, int], ...]  # (driver joint, body index)
    sensor: tuple[int, tuple[float, float], float] | None  # (body, local point, axis) of the accelerometer
    surfaces: dict[str, JointSurfaces] = field(default_factory=dict)
    warnings: tuple[str, ...] = ()

    @property
    def n(self) -> int:
        return self.q0.size

    @property
    def m(self) -> int:
        return len(self.row_joints)

    @property
    def speed(self) -> float:
        return self.bench.speed

    @property
    def v0(self) -> np.ndarray:
        """Initial velocities at the bench's motor speed."""
        return self.v_unit * self.bench.speed

    def body_index(self, name: str) -> int:
        return self.bodies.index(name)

    def clearance_params(self, joint: str) -> dict[str, float]:
        """Geometry and contact parameters of clearance joint ``joint`` (SI)."""
        k = self.clearance_joints.index(joint)
        p = self.params.clr_p[k]
        return {"bearing_radius": p[K.CLR_R1], "journal_radius": p[K.CLR_R2], "stiffness": p[K.CLR_K],
                "exponent": p[K.CLR_N], "restitution": p[K.CLR_CE], "law": int(p[K.CLR_LAW]),
                "friction_coefficient": p[K.CLR_CF]}

    def work(self) -> K.Workspace:
        """Fresh work arrays for the kernel."""
        return K.workspace(self.params)


def dense_jacobian(P: K.Params, Jv: np.ndarray, n: int) -> np.ndarray:
    """Phi_q (m x n) as a dense matrix from the kernel's compact Jacobian values ``Jv`` (``Workspace.Jv``,
    filled by ``kernel.constraints``) and the body pattern of ``P``."""
    jb = P.jb
    J = np.zeros((jb.shape[0], n))
    for k in range(jb.shape[0]):
        for s in range(2):
            if jb[k, s] >= 0:
                J[k, 3 * jb[k, s]: 3 * jb[k, s] + 3] += Jv[k, s]
    return J


def _anchors(bench: Bench) -> tuple[dict[str, tuple[float, float]], dict[str, float]]:
    """What fixes the first bodies' places: joint positions known beforehand (the bench's assembly points
    and the pins to the frame) and body angles known beforehand (driver phases, sliders on frame guides)."""
    known: dict[str, tuple[float, float]] = dict(bench.assembly)
    for j in bench.joints:
        if j.kind == "revolute" and GROUND in j.bodies and j.name not in known:
            known[j.name] = bench.ground_points[j.points[j.bodies.index(GROUND)]]
    angle: dict[str, float] = {}
    for d in bench.drivers:
        angle[next(x for x in bench.joint(d.joint).bodies if x != GROUND)] = d.phase
    for j in bench.joints:
        if j.kind == "prismatic" and j.bodies[0] == GROUND:
            angle[j.bodies[1]] = j.axis
    return known, angle


def _guess(bench: Bench, index: dict[str, int]) -> np.ndarray:
    """Initial positions from the bench's assembly points, ground points and driver phases."""
    known, angle = _anchors(bench)
    q = np.zeros(3 * len(index))
    placed: set[str] = set()

    def place(name: str, force: bool) -> bool:
        pairs = [(np.array(bench.body(name).points[j.points[j.bodies.index(name)]]), np.array(known[j.name]))
                 for j in bench.joints if j.kind == "revolute" and name in j.bodies and j.name in known]
        for j in bench.joints:  # a prismatic point on a guide fixed to the frame lies on the guide line
            if j.kind == "prismatic" and j.bodies == (GROUND, name) and not pairs:
                pairs.append((np.array(bench.body(name).points[j.points[1]]),
                              np.array(bench.ground_points[j.points[0]])))
        if len(pairs) >= 2:
            (s0, p0), (s1, p1) = pairs[0], pairs[1]
            ds, dp = s1 - s0, p1 - p0
            th = math.atan2(dp[1], dp[0]) - math.atan2(ds[1], ds[0])
            th = angle.get(name, th)
        elif len(pairs) == 1 and (name in angle or force):
            s0, p0 = pairs[0]
            th = angle.get(name, 0.0)
        elif force:
            s0, p0, th = np.zeros(2), np.zeros(2), angle.get(name, 0.0)
        else:
            return False
        c, s = math.cos(th), math.sin(th)
        r = p0 - np.array([c * s0[0] - s * s0[1], s * s0[0] + c * s0[1]])
        i = index[name]
        q[3 * i: 3 * i + 3] = (r[0], r[1], th)
        placed.add(name)
        for j in bench.joints:
            if j.kind == "revolute" and name in j.bodies and j.name not in known:
                sl = bench.body(name).points[j.points[j.bodies.index(name)]]
                known[j.name] = (r[0] + c * sl[0] - s * sl[1], r[1] + s * sl[0] + c * sl[1])
        return True

    while len(placed) < len(index):
        todo = [b.name for b in bench.bodies if b.name not in placed]
        if not any(place(name, False) for name in todo):
            place(todo[0], True)
    return q


def _assemble(bench: Bench, P, row_joints, n: int, q: np.ndarray) -> np.ndarray:
    """Newton (least squares) on all ideal constraints at t = 0; BenchError if it does not close."""
    W = K.workspace(P)
    v = np.zeros(n)
    for _ in range(60):
        K.constraints(0.0, q, v, bench.speed, P, W)
        if np.max(np.abs(W.phi), initial=0.0) <= _ASSEMBLY_TOL:
            return q
        J = dense_jacobian(P, W.Jv, n)
        dq = np.linalg.lstsq(J, -W.phi, rcond=None)[0]
        step = np.max(np.abs(dq))
        q = q + (dq if step < 0.2 else dq * (0.2 / step))
    k = int(np.argmax(np.abs(W.phi)))
    raise BenchError(bench.path or bench.name, "assembly", row_joints[k],
                     f"mechanism does not assemble at t = 0: largest residual {abs(W.phi[k]):.3g} "
                     f"(m or rad) at joint {row_joints[k]}; check lengths, ground points and [assembly]")


def build_scene(bench: Bench, *, clearances: Mapping[str, float | None] | None = None,
                surfaces: Mapping[str, JointSurfaces] | None = None,
                forces: Sequence[Spring | Torque] = ()) -> Scene:
    """Build the scene of ``bench``: assemble at t = 0, choose what to compute.

    clearances: {joint: radial clearance m, or None for an ideal pin} overriding the bench file.
    surfaces: {joint: JointSurfaces} worn surfaces (default: the files the bench names, if any).
    forces: extra force elements (springs, dampers, torques).
    Raises BenchError if the mechanism does not assemble.
    """
    if clearances:
        bench = bench.with_clearances(clearances)
    if surfaces is None:
        surfaces = surfaces_from_bench(bench)
    clear_names = {j.name for j in bench.clearance_joints}
    unknown = set(surfaces) - clear_names
    if unknown:
        raise KeyError(f"{bench.name}: surfaces for {sorted(unknown)}, which are not clearance joints "
                       f"({sorted(clear_names)})")
    index = {b.name: i for i, b in enumerate(bench.bodies)}
    n = 3 * len(index)
    ideal_P, ideal_rows, _, _, _ = pack_params(bench, index, clear_names, forces, {})
    q0 = _assemble(bench, ideal_P, ideal_rows, n, _guess(bench, index))
    # velocities: minimum kinetic-energy solution of the ideal velocity equations (exact at dof 0)
    v0 = np.zeros(n)
    K.project(0.0, q0, v0, 1.0, ideal_P, K.workspace(ideal_P), _ASSEMBLY_TOL, 20)  # per unit motor speed
    P, row_joints, reaction_rows, clr_names, drivers = pack_params(bench, index, set(), forces, surfaces)
    # springs without a free length take their length at t = 0
    spr_p = P.spr_p
    for k in range(spr_p.shape[0]):
        if spr_p[k, 6] < 0:
            bi, bj = P.spr_b[k]
            pi = _point(q0, bi, spr_p[k, 0:2])
            pj = _point(q0, bj, spr_p[k, 2:4])
            spr_p[k, 6] = float(np.hypot(*(pj - pi)))
    m = len(row_joints)
    Wd = K.workspace(P)
    K.constraints(0.0, q0, v0 * bench.speed, bench.speed, P, Wd)
    rank = int(np.linalg.matrix_rank(dense_jacobian(P, Wd.Jv, n))) if m else 0
    dof = n - rank
    notes = []
    for j in bench.clearance_joints:
        if j.clearance.contact.law == "lankarani-nikravesh" and j.clearance.contact.restitution < LOW_RESTITUTION:
            msg = (f"{bench.name}: joint {j.name}: restitution {j.clearance.contact.restitution} is low for the "
                   "Lankarani-Nikravesh law (valid for restitution near 1); use law = \"flores\"")
            warnings.warn(msg, UserWarning, stacklevel=2)
            notes.append(msg)
    if not clr_names and dof == 0:
        what = "kinematics + inverse dynamics (fully driven, ideal joints: 0 DOF)"
    elif clr_names:
        what = (f"dynamics: {len(clr_names)} clearance joint(s) {', '.join(clr_names)} "
                f"({2 * len(clr_names)} clearance DOF, {dof} DOF in all; {n} coordinates, {m} constraints)")
    else:
        what = f"dynamics: {dof} DOF ({n} coordinates, {m} constraints)"
    sensor = None
    try:
        s = bench.sensor("accelerometer")
        sensor = (index[s.body], tuple(bench.body(s.body).points[s.point]), s.axis)
    except KeyError:
        pass
    return Scene(bench=bench, bodies=tuple(index), clearance_joints=clr_names, dof=dof, description=what,
                 q0=q0, v_unit=v0, params=P, reaction_rows=reaction_rows, row_joints=row_joints,
                 drivers=drivers, sensor=sensor, surfaces=dict(surfaces), warnings=tuple(notes))


def _point(q: np.ndarray, b: int, s: np.ndarray) -> np.ndarray:
    if b < 0:
        return np.array(s, dtype=float)
    c, sn = math.cos(q[3 * b + 2]), math.sin(q[3 * b + 2])
    return np.array([q[3 * b] + c * s[0] - sn * s[1], q[3 * b + 1] + sn * s[0] + c * s[1]])
