"""A bench packed into the compiled kernel's parameters (:class:`~wearbench.model.kernel.Params`).

One packer per element kind: bodies (inverse masses, gravity), ideal pins, clearance joints as
contacts (with their worn depths), prismatic joints, drivers, force elements (the classes
:class:`Spring` and :class:`Torque`), and the constant pattern of the constraint Jacobian.
:func:`pack_params` runs them in the kernel's row order. Imports the bench dataclasses, the
surfaces contract and the model's ``contact`` and ``kernel``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from wearbench.bench.schema import GROUND, Bench, BenchError, Joint
from wearbench.model import kernel as K
from wearbench.model.contact import LAWS, contact_stiffness
from wearbench.model.surface_tables import TABLE_ROWS, surface_curvature, surface_tables
from wearbench.model.surfaces import JointSurfaces

__all__ = ["Spring", "Torque", "pack_params"]


@dataclass(frozen=True)
class Spring:
    """Point-to-point spring-damper: tension k (l - l0) + c dl/dt between two body points.

    ``body_*`` is a body name or "frame"; ``point_*`` a named point of that body (or of the frame)
    or local coordinates (m). Stiffness N/m, damping N s/m, free length m (None: length at t = 0).
    """

    body_i: str
    point_i: str | tuple[float, float]
    body_j: str
    point_j: str | tuple[float, float]
    stiffness: float = 0.0
    damping: float = 0.0
    free_length: float | None = None


@dataclass(frozen=True)
class Torque:
    """Applied torque on a body: T = torque - damping * omega (N m; damping N m s/rad)."""

    body: str
    torque: float = 0.0
    damping: float = 0.0



def _local(bench: Bench, body: str, point: str | tuple[float, float]) -> tuple[float, float]:
    if not isinstance(point, str):
        return (float(point[0]), float(point[1]))
    pts = bench.ground_points if body == GROUND else bench.body(body).points
    if point not in pts:
        raise KeyError(f"{bench.name}: {body} has no point {point!r}; points: {sorted(pts)}")
    return tuple(pts[point])


def _pin_pairs(joint: Joint) -> list[tuple[int, int]]:
    """A pin shared by N bodies is N-1 pairs, each chained to the first body."""
    return [(0, i) for i in range(1, len(joint.bodies))]


def _ia(x, shape) -> np.ndarray:
    return np.array(x, dtype=np.int64).reshape(shape)


def _fa(x, shape) -> np.ndarray:
    return np.array(x, dtype=float).reshape(shape)


def _pack_bodies(bench: Bench, index: dict[str, int]) -> tuple[np.ndarray, np.ndarray]:
    """Inverse masses and inertias, and the constant generalised forces (gravity), per coordinate."""
    n = 3 * len(index)
    minv, fext = np.zeros(n), np.zeros(n)
    for body in bench.bodies:
        i = index[body.name]
        minv[3 * i: 3 * i + 3] = (1 / body.mass, 1 / body.mass, 1 / body.inertia)
        fext[3 * i: 3 * i + 2] = (body.mass * bench.gravity[0], body.mass * bench.gravity[1])
    return minv, fext


def _pack_pins(bench: Bench, b, pinned: list[Joint]):
    """Ideal pins: body pairs, local points, and the reaction rows (name prefix, first row) of each."""
    rev_b, rev_s, reaction_rows = [], [], []
    for j in pinned:
        for a, c in _pin_pairs(j):
            prefix = j.name if len(j.bodies) == 2 else f"{j.name}_{j.bodies[c]}"
            reaction_rows.append((prefix, 2 * len(rev_b)))
            rev_b.append((b(j.bodies[a]), b(j.bodies[c])))
            rev_s.append(_local(bench, j.bodies[a], j.points[a]) + _local(bench, j.bodies[c], j.points[c]))
    return _ia(rev_b, (-1, 2)), _fa(rev_s, (-1, 4)), reaction_rows


def _pack_clearances(bench: Bench, b, joints: list[Joint], surfaces: Mapping[str, JointSurfaces]):
    """Clearance joints as contacts: bearing/journal bodies, the CLR_* parameter rows, worn depths
    and their tables (``midpoints.surface_tables``)."""
    clr_b, clr_p, surf_list = [], [], []
    for j in joints:
        cl = j.clearance
        ib = j.bodies.index(cl.bearing_body)
        ij = j.bodies.index(cl.journal_body)
        law = cl.contact
        stiff = contact_stiffness(cl.bearing_material.youngs_modulus, cl.bearing_material.poisson_ratio,
                                  cl.journal_material.youngs_modulus, cl.journal_material.poisson_ratio,
                                  cl.bearing_radius, cl.journal_radius, law.stiffness)
        clr_b.append((b(cl.bearing_body), b(cl.journal_body)))
        s_i = _local(bench, cl.bearing_body, j.points[ib])
        s_j = _local(bench, cl.journal_body, j.points[ij])
        surf = surfaces.get(j.name)
        row = np.zeros(K.NCLR)
        row[[K.CLR_SIX, K.CLR_SIY, K.CLR_SJX, K.CLR_SJY]] = s_i + s_j
        row[K.CLR_R1], row[K.CLR_R2], row[K.CLR_K] = cl.bearing_radius, cl.journal_radius, stiff
        row[K.CLR_N], row[K.CLR_CE], row[K.CLR_LAW] = law.exponent, law.restitution, LAWS[law.law]
        row[K.CLR_CF], row[K.CLR_FV0], row[K.CLR_FVM] = (law.friction_coefficient, law.friction_v0,
                                                      law.friction_vm)
        # an all-zero surface is the even clearance: same code path, bit-identical results
        worn = surf is not None and (surf.bearing.any() or surf.journal.any())
        row[K.CLR_WORN] = 1.0 if worn else 0.0
        clr_p.append(row)
        surf_list.append(surf)
    nmax = max([3] + [max(s.bearing.size, s.journal.size) for s in surf_list if s is not None])
    surf = np.zeros((len(clr_b), 2, nmax))
    surf_n = np.full((len(clr_b), 2), 3, dtype=np.int64)
    for k, s in enumerate(surf_list):
        if s is not None:
            surf[k, 0, :s.bearing.size] = s.bearing
            surf[k, 1, :s.journal.size] = s.journal
            surf_n[k] = (s.bearing.size, s.journal.size)
    tables = np.zeros((len(clr_b), 2, TABLE_ROWS, 2 * nmax))  # the contact search's, once per surface
    for k in range(len(clr_b)):
        for side in (0, 1):
            n = surf_n[k, side]
            tables[k, side, :, :2 * n] = surface_tables(surf[k, side], n)
            clr_p[k][K.CLR_CURV] += surface_curvature(tables[k, side], n)
    return _ia(clr_b, (-1, 2)), _fa(clr_p, (-1, K.NCLR)), surf, surf_n, tables


def _pack_prismatics(bench: Bench, b, joints: list[Joint]):
    """Prismatic joints: guide and sliding bodies, their local points and the axis."""
    pri_b, pri_s = [], []
    for j in joints:
        if j.bodies[1] == GROUND:
            raise BenchError(bench.path or bench.name, f"joint {j.name}.bodies", list(j.bodies),
                             "expected the guide (frame or carrier) first and the sliding body second")
        pri_b.append((b(j.bodies[0]), b(j.bodies[1])))
        pri_s.append(_local(bench, j.bodies[0], j.points[0]) + _local(bench, j.bodies[1], j.points[1]) + (j.axis,))
    return _ia(pri_b, (-1, 2)), _fa(pri_s, (-1, 5))


def _pack_drivers(bench: Bench, index: dict[str, int]):
    """Drivers: the driven body, (ratio, phase), and (joint, body index) of each."""
    drv_b, drv_p, drivers = [], [], []
    for d in bench.drivers:
        body = next(x for x in bench.joint(d.joint).bodies if x != GROUND)
        drv_b.append(index[body])
        drv_p.append((d.ratio, d.phase))
        drivers.append((d.joint, index[body]))
    return _ia(drv_b, (-1,)), _fa(drv_p, (-1, 2)), drivers


def _pack_forces(bench: Bench, b, index: dict[str, int], forces: Sequence[Spring | Torque]):
    """Force elements: point-to-point spring-dampers and applied torques."""
    spr_b, spr_p, trq_b, trq_p = [], [], [], []
    for f in forces:
        if isinstance(f, Spring):
            spr_b.append((b(f.body_i), b(f.body_j)))
            spr_p.append(_local(bench, f.body_i, f.point_i) + _local(bench, f.body_j, f.point_j)
                         + (f.stiffness, f.damping, -1.0 if f.free_length is None else f.free_length))
        elif isinstance(f, Torque):
            trq_b.append(index[f.body])
            trq_p.append((f.torque, f.damping))
        else:
            raise TypeError(f"force element {f!r}: expected Spring or Torque")
    return _ia(spr_b, (-1, 2)), _fa(spr_p, (-1, 7)), _ia(trq_b, (-1,)), _fa(trq_p, (-1, 2))


def _pack_jacobian_pattern(rev_b: np.ndarray, pri_b: np.ndarray, drv_b: np.ndarray, nb: int):
    """The constant body pattern of Phi_q (two rows per pin and prismatic joint, one per driver)
    and the (row, slot) pairs touching each body."""
    jb = []
    for bi, bj in rev_b:
        jb += [(bi, bj), (bi, bj)]
    for bi, bj in pri_b:
        jb += [(bi, bj), (bi, bj)]
    for bd in drv_b:
        jb.append((bd, -1))
    jb_a = _ia(jb, (-1, 2))
    rows: list[list[tuple[int, int]]] = [[] for _ in range(nb)]
    for k, (bi, bj) in enumerate(jb_a):
        for s, bb in enumerate((bi, bj)):
            if bb >= 0:
                rows[bb].append((k, s))
    kmax = max([1] + [len(r) for r in rows])
    body_rows = np.zeros((nb, kmax, 2), dtype=np.int64)
    body_nrows = np.array([len(r) for r in rows], dtype=np.int64)
    for bb, r in enumerate(rows):
        for x, ks in enumerate(r):
            body_rows[bb, x] = ks
    # envelope of S = Phi_q M^-1 Phi_q^T: the first row sharing a body with each row
    s_first = np.array([min([k] + [kk for bb in pair if bb >= 0 for kk, _ in rows[bb]]) for k, pair in enumerate(jb)],
                       dtype=np.int64)
    return jb_a, body_rows, body_nrows, s_first


def pack_params(bench: Bench, index: dict[str, int], ideal: set[str], forces: Sequence[Spring | Torque],
              surfaces: Mapping[str, JointSurfaces]):
    """Pack the bench into the kernel's parameters (:class:`~wearbench.model.kernel.Params`), one
    packer per element kind; clearance joints not in ``ideal`` become contacts."""
    def b(name: str) -> int:
        return -1 if name == GROUND else index[name]

    pinned = [j for j in bench.joints if j.kind == "revolute" and (j.clearance is None or j.name in ideal)]
    contacts = [j for j in bench.joints if j.kind == "revolute" and j.clearance is not None and j.name not in ideal]
    prismatic = [j for j in bench.joints if j.kind == "prismatic"]
    minv, fext = _pack_bodies(bench, index)
    rev_b, rev_s, reaction_rows = _pack_pins(bench, b, pinned)
    clr_b, clr_p, surf, surf_n, surf_t = _pack_clearances(bench, b, contacts, surfaces)
    pri_b, pri_s = _pack_prismatics(bench, b, prismatic)
    drv_b, drv_p, drivers = _pack_drivers(bench, index)
    spr_b, spr_p, trq_b, trq_p = _pack_forces(bench, b, index, forces)
    jb, body_rows, body_nrows, s_first = _pack_jacobian_pattern(rev_b, pri_b, drv_b, len(index))
    # constraint row -> joint name, in kernel order (pins, prismatic, drivers)
    row_joints = ([j.name for j in pinned for _ in range(2 * len(_pin_pairs(j)))]
                  + [j.name for j in prismatic for _ in range(2)] + [d.joint for d in bench.drivers])
    P = K.Params(minv=minv, fext=fext, rev_b=rev_b, rev_s=rev_s, pri_b=pri_b, pri_s=pri_s, drv_b=drv_b,
                 drv_p=drv_p, clr_b=clr_b, clr_p=clr_p, surf=surf, surf_n=surf_n, surf_t=surf_t, spr_b=spr_b, spr_p=spr_p,
                 trq_b=trq_b, trq_p=trq_p, jb=jb, body_rows=body_rows, body_nrows=body_nrows, s_first=s_first,
                 profile=np.zeros((0, 3)))
    return P, tuple(row_joints), tuple(reaction_rows), tuple(j.name for j in contacts), tuple(drivers)
