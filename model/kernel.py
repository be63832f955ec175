"""Compiled core of the planar multibody model: constraints, forces, accelerations, projection.

Holds numba-compiled (``@njit(cache=True)``) functions on flat arrays; the scene (``scene.py``)
packs a mechanism into the named record ``P`` (:class:`Params`) described below and the integrators (``integrators.py``)
call :func:`accel` and :func:`project`. What the kernels evaluate travels as named records (namedtuples numba
compiles, built by keyword): :class:`Params`, the work arrays :class:`Workspace`, the mechanism at a run's
settings :class:`Model` (P, motor speed, Baumgarte coefficients, contact modes, workspace) and, inside the
contact force, one clearance joint at the state (:class:`Pair`) and a contact zone
(``worn_contact.Zone``). Imports numpy, numba, ``contact`` and ``worn_contact`` only.

Coordinates: q = (x, y, theta) of each moving body's centre of mass (absolute coordinates), v = dq/dt.
Equations of motion (paper eq. 29-30) with a diagonal mass matrix M:
    M a + Phi_q^T lam = g,   Phi_q a = gamma - 2 alpha Phi' - beta^2 Phi,
solved through the Schur complement S = Phi_q M^-1 Phi_q^T (Cholesky, m x m). Each constraint row
touches at most two bodies, so Phi_q is stored compactly: body index ``Jb[k, s]`` (-1 = none) and
the three entries ``Jv[k, s, :]`` per slot s.

P = Params(minv, fext, rev_b, rev_s, pri_b, pri_s, drv_b, drv_p, clr_b, clr_p, surf, surf_n, surf_t,
           spr_b, spr_p, trq_b, trq_p, jb, body_rows, body_nrows, s_first, profile), a named tuple numba compiles:
- minv (n,): inverse masses/inertias; fext (n,): constant generalised forces (gravity).
- rev_b (nr, 2), rev_s (nr, 4): ideal pin pairs: bodies (-1 = frame) and local points
  (x_i, y_i, x_j, y_j); constraint r_i + A_i s_i - r_j - A_j s_j = 0 (2 rows).
- pri_b (np, 2), pri_s (np, 5): prismatic joints: point s_j of body j on the line through s_i of
  body i with direction ``axis`` (in body i's frame); theta_j - theta_i = axis (2 rows).
- drv_b (nd,), drv_p (nd, 2): drivers theta_b = ratio * theta_motor(t) + phase (1 row).
- clr_b (nc, 2), clr_p (nc, NCLR): clearance joints (bearing body, journal body), see CLR_* below.
- surf (nc, 2, nmax), surf_n (nc, 2): worn depths of bearing [0] and journal [1], regions used;
  surf_t (nc, 2, TABLE_ROWS, 2 nmax): their ``midpoints.surface_tables``, the contact search's tables.
- spr_b (ns, 2), spr_p (ns, 7): point-to-point spring-dampers (x_i, y_i, x_j, y_j, k, c, l0).
- trq_b (nt,), trq_p (nt, 2): applied torques T = T0 - c_rot * omega on a body.
- jb (m, 2): constant body pattern of Phi_q; body_rows (nb, kmax, 2), body_nrows (nb,): rows
  (row, slot) touching each body; s_first (m,): first row sharing a body with each row (the
  envelope of S, which its Cholesky factor keeps: the solve skips what lies outside).
- profile (k, 3): motor speed profile rows (time, angle, speed), empty for constant ``speed``.

Status codes returned by kernels: 0 ok, 1 singular constraint Jacobian (singular pose),
2 projection did not converge.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit
from wearbench.model.contact import (
    friction_force,
    impact_speed,
    normal_force,
)
from wearbench.model.worn_contact import Gap, Zone, contact_zones, zone_penetrations

Params = namedtuple("Params", "minv fext rev_b rev_s pri_b pri_s drv_b drv_p clr_b clr_p surf surf_n surf_t "
                               "spr_b spr_p trq_b trq_p jb body_rows body_nrows s_first profile")
# work arrays of the kernels, built once per run by :func:`workspace`: constraints (phi, Phi_q values Jv,
# gamma, nu = -Phi_t), generalised forces g, the Schur complement S with its right-hand side and solution
# lam, an n-vector tmp, the bodies' cos/sin and the worn-contact search's midpoint samples buf
Workspace = namedtuple("Workspace", "phi Jv gam nu g S rhs lam tmp cs sn buf")
# the mechanism as the kernels evaluate it: parameters P, motor speed (rad/s; a speed profile is P's), Baumgarte
# (alpha, beta), contact modes per clearance joint (inc: in contact, v0i: impact speed), the workspace W
Model = namedtuple("Model", "P speed alpha beta inc v0i W")
# one clearance joint at the state: bearing and journal bodies, bearing and journal centres, angular velocities,
# contact mode (in contact, impact speed); scalars only (its parameter row travels as an argument)
Pair = namedtuple("Pair", "bi bj pix piy pjx pjy wi wj inc v0")

# clearance parameter columns (CLR_WORN: 1 for worn surfaces; CLR_CURV: their largest |h_b''| + |h_j''|)
CLR_SIX, CLR_SIY, CLR_SJX, CLR_SJY, CLR_R1, CLR_R2, CLR_K, CLR_N, CLR_CE, CLR_LAW, CLR_CF, \
    CLR_FV0, CLR_FVM, CLR_WORN, CLR_CURV = range(15)
NCLR = 15
# contact output columns (cout)
CO_EX, CO_EY, CO_PEN, CO_FN, CO_FT, CO_VN, CO_VT, CO_OMEGA, CO_PHIB, CO_PHIJ = range(10)
NCO = 10

OK, SINGULAR, NO_CONVERGENCE = 0, 1, 2


def workspace(P: Params) -> Workspace:
    """Fresh work arrays for the kernels of the mechanism packed in ``P``."""
    n, m = P.minv.shape[0], P.jb.shape[0]
    return Workspace(phi=np.zeros(m), Jv=np.zeros((m, 2, 3)), gam=np.zeros(m), nu=np.zeros(m), g=np.zeros(n),
                     S=np.zeros((m, m)), rhs=np.zeros(m), lam=np.zeros(m), tmp=np.zeros(n), cs=np.zeros(n // 3),
                     sn=np.zeros(n // 3), buf=np.zeros(P.surf.shape[2]))


@njit(cache=True, inline="always")
def _fill(a, value):
    """a[:] = value as a plain loop (numba's slice assignment costs ~40 ns per call)."""
    for i in range(a.shape[0]):
        a[i] = value


@njit(cache=True, inline="always")
def _rot(q, b, sx, sy):
    """A_b s (global components of a body-fixed vector)."""
    if b < 0:
        return sx, sy
    c = math.cos(q[3 * b + 2])
    s = math.sin(q[3 * b + 2])
    return c * sx - s * sy, s * sx + c * sy


@njit(cache=True, inline="always")
def _pos(q, b, sx, sy):
    """r_b + A_b s (global position of a body-fixed point; ground is b < 0)."""
    rx, ry = _rot(q, b, sx, sy)
    if b < 0:
        return rx, ry
    return q[3 * b] + rx, q[3 * b + 1] + ry


@njit(cache=True, inline="always")
def _pos_c(q, cs, sn, b, sx, sy):
    """_pos with the body's cos/sin precomputed."""
    if b < 0:
        return sx, sy
    return q[3 * b] + cs[b] * sx - sn[b] * sy, q[3 * b + 1] + sn[b] * sx + cs[b] * sy


@njit(cache=True, inline="always")
def _rot_c(cs, sn, b, sx, sy):
    if b < 0:
        return sx, sy
    return cs[b] * sx - sn[b] * sy, sn[b] * sx + cs[b] * sy


@njit(cache=True, inline="always")
def _omega(v, b):
    return 0.0 if b < 0 else v[3 * b + 2]


@njit(cache=True)
def point_along(x, y, th, vx, vy, w, ax, ay, al, sx, sy, axis):
    """Position, velocity and acceleration along an axis of a point fixed in a body: the one place the
    sensor's (and any body point's) kinematics are formed. (x, y, th), (vx, vy, w), (ax, ay, al): the
    body's coordinates and their first and second derivatives (scalars, or arrays of equal shape, one
    value per time); (sx, sy): the point in the body; axis: the measuring axis' angle in the body."""
    c, s = np.cos(th), np.sin(th)
    px, py = c * sx - s * sy, s * sx + c * sy
    ux, uy = np.cos(th + axis), np.sin(th + axis)
    pos = (x + px) * ux + (y + py) * uy
    vel = (vx - w * py) * ux + (vy + w * px) * uy
    acc = (ax - al * py - w * w * px) * ux + (ay + al * px - w * w * py) * uy
    return pos, vel, acc


@njit(cache=True, _nrt=False)
def motor_angle(t, speed, profile):
    """Motor angle (rad, 0 at t = 0), speed (rad/s) and acceleration (rad/s^2) at time t (s).

    Constant ``speed`` when ``profile`` is empty; otherwise profile (k, 3) holds rows
    (time, angle, speed) with the speed linear between rows (the angle its exact integral) and held
    constant after the last row.
    """
    npts = profile.shape[0]
    if npts == 0:
        return speed * t, speed, 0.0
    lo, hi = 0, npts - 1  # binary search: profile[lo, 0] <= t < profile[lo + 1, 0]
    if t >= profile[hi, 0]:
        lo = hi
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if profile[mid, 0] <= t:
            lo = mid
        else:
            hi = mid
    i = lo
    tau = t - profile[i, 0]
    if i + 1 < npts:
        acc = (profile[i + 1, 2] - profile[i, 2]) / (profile[i + 1, 0] - profile[i, 0])
    else:
        acc = 0.0
    return profile[i, 1] + profile[i, 2] * tau + 0.5 * acc * tau * tau, profile[i, 2] + acc * tau, acc


@njit(cache=True, inline="always")
def constraints(t, q, v, speed, P, W):
    """Fill Phi (m), compact Phi_q values Jv (m, 2, 3), gamma (m) and nu = -Phi_t (m) of the workspace W, and the
    bodies' cos/sin (W.cs, W.sn)."""
    rev_b, rev_s, pri_b, pri_s, drv_b, drv_p = P.rev_b, P.rev_s, P.pri_b, P.pri_s, P.drv_b, P.drv_p
    phi, Jv, gam, nu, cs, sn = W.phi, W.Jv, W.gam, W.nu, W.cs, W.sn
    nb = q.shape[0] // 3
    for b in range(nb):
        cs[b] = math.cos(q[3 * b + 2])
        sn[b] = math.sin(q[3 * b + 2])
    # Jv's entries outside the fixed pattern written below are zero from :func:`workspace` and never written
    k = 0
    for r in range(rev_b.shape[0]):
        bi, bj = rev_b[r, 0], rev_b[r, 1]
        pix, piy = _pos_c(q, cs, sn, bi, rev_s[r, 0], rev_s[r, 1])
        pjx, pjy = _pos_c(q, cs, sn, bj, rev_s[r, 2], rev_s[r, 3])
        ax, ay = _rot_c(cs, sn, bi, rev_s[r, 0], rev_s[r, 1])
        bx, by = _rot_c(cs, sn, bj, rev_s[r, 2], rev_s[r, 3])
        wi, wj = _omega(v, bi), _omega(v, bj)
        phi[k] = pix - pjx
        phi[k + 1] = piy - pjy
        # d(A s)/dtheta = (-ay, ax)
        Jv[k, 0, 0] = 1.0
        Jv[k, 0, 2] = -ay
        Jv[k + 1, 0, 1] = 1.0
        Jv[k + 1, 0, 2] = ax
        Jv[k, 1, 0] = -1.0
        Jv[k, 1, 2] = by
        Jv[k + 1, 1, 1] = -1.0
        Jv[k + 1, 1, 2] = -bx
        gam[k] = ax * wi * wi - bx * wj * wj
        gam[k + 1] = ay * wi * wi - by * wj * wj
        nu[k] = 0.0
        nu[k + 1] = 0.0
        k += 2
    for r in range(pri_b.shape[0]):
        bi, bj = pri_b[r, 0], pri_b[r, 1]
        axis = pri_s[r, 4]
        pix, piy = _pos_c(q, cs, sn, bi, pri_s[r, 0], pri_s[r, 1])
        pjx, pjy = _pos_c(q, cs, sn, bj, pri_s[r, 2], pri_s[r, 3])
        ax, ay = _rot_c(cs, sn, bi, pri_s[r, 0], pri_s[r, 1])
        bx, by = _rot_c(cs, sn, bj, pri_s[r, 2], pri_s[r, 3])
        nx, ny = _rot_c(cs, sn, bi, -math.sin(axis), math.cos(axis))
        wi, wj = _omega(v, bi), _omega(v, bj)
        dx, dy = pjx - pix, pjy - piy
        # d' = vj + w_j k x (A_j s_j) - vi - w_i k x (A_i s_i)
        vix = 0.0 if bi < 0 else v[3 * bi]
        viy = 0.0 if bi < 0 else v[3 * bi + 1]
        vjx = 0.0 if bj < 0 else v[3 * bj]
        vjy = 0.0 if bj < 0 else v[3 * bj + 1]
        ddx = vjx - wj * by - vix + wi * ay
        ddy = vjy + wj * bx - viy - wi * ax
        phi[k] = nx * dx + ny * dy
        Jv[k, 0, 0] = -nx
        Jv[k, 0, 1] = -ny
        # d n/dtheta_i = (-ny, nx); d(A_i s_i)/dtheta_i = (-ay, ax)
        Jv[k, 0, 2] = (-ny * dx + nx * dy) - (nx * -ay + ny * ax)
        Jv[k, 1, 0] = nx
        Jv[k, 1, 1] = ny
        Jv[k, 1, 2] = nx * -by + ny * bx
        gam[k] = ((nx * dx + ny * dy) * wi * wi - 2.0 * wi * (-ny * ddx + nx * ddy)
                  + nx * (bx * wj * wj - ax * wi * wi) + ny * (by * wj * wj - ay * wi * wi))
        nu[k] = 0.0
        thi = 0.0 if bi < 0 else q[3 * bi + 2]
        phi[k + 1] = q[3 * bj + 2] - thi - axis
        Jv[k + 1, 0, 2] = -1.0
        Jv[k + 1, 1, 2] = 1.0
        gam[k + 1] = 0.0
        nu[k + 1] = 0.0
        k += 2
    th_m, w_m, a_m = motor_angle(t, speed, P.profile)
    for r in range(drv_b.shape[0]):
        b = drv_b[r]
        phi[k] = q[3 * b + 2] - (drv_p[r, 0] * th_m + drv_p[r, 1])
        Jv[k, 0, 2] = 1.0
        gam[k] = drv_p[r, 0] * a_m
        nu[k] = drv_p[r, 0] * w_m
        k += 1


@njit(cache=True, inline="always")
def _apply(g, b, fx, fy, px, py, q):
    """Add force (fx, fy) acting at global point (px, py) of body b to the generalised forces."""
    if b < 0:
        return
    g[3 * b] += fx
    g[3 * b + 1] += fy
    g[3 * b + 2] += (px - q[3 * b]) * fy - (py - q[3 * b + 1]) * fx


@njit(cache=True, inline="always")
def _vel(q, v, b, px, py):
    """Velocity of the material point of body b at global position (px, py)."""
    if b < 0:
        return 0.0, 0.0
    w = v[3 * b + 2]
    return v[3 * b] - w * (py - q[3 * b + 1]), v[3 * b + 1] + w * (px - q[3 * b])


@njit(cache=True, _nrt=False)
def _zone_force(q, v, pair, p, nx, ny, pen, zone, scale, g):
    """Apply the normal and friction force of one contact zone of the joint ``pair`` (:class:`Pair`, its
    parameter row ``p``) to g;
    returns (fn, ft, vn, vt). (nx, ny): the zone's normal from the bearing's centre; pen: its penetration;
    ``zone``: its :class:`~wearbench.model.worn_contact.Zone` (worn depths and their slopes there, zero for
    new surfaces); the force scaled by ``scale`` in [0, 1]. The contact points on each body are the
    surface points along the normal; the penetration rate is the normal speed of the journal's centre
    relative to the bearing's (rolling terms are tangential) plus the worn surfaces' sweep."""
    bi, bj, pix, piy, pjx, pjy, wi, wj, inck, v0k = pair
    hb, hj = zone.hb, zone.hj
    tx, ty = -ny, nx
    qix, qiy = pix + (p[CLR_R1] + hb) * nx, piy + (p[CLR_R1] + hb) * ny
    qjx, qjy = pjx + (p[CLR_R2] - hj) * nx, pjy + (p[CLR_R2] - hj) * ny
    vix, viy = _vel(q, v, bi, qix, qiy)
    vjx, vjy = _vel(q, v, bj, qjx, qjy)
    cix, ciy = _vel(q, v, bi, pix, piy)
    cjx, cjy = _vel(q, v, bj, pjx, pjy)
    vn = nx * (cjx - cix) + ny * (cjy - ciy) + zone.slope_b * wi + zone.slope_j * wj
    vt = (vjx - vix) * tx + (vjy - viy) * ty
    fn = 0.0
    ft = 0.0
    if pen > 0.0 and scale > 0.0:
        v0 = v0k if inck != 0 else impact_speed(vn)
        fn = scale * normal_force(pen, vn, p[CLR_K], p[CLR_N], p[CLR_CE], v0, int(p[CLR_LAW]))
        ft = friction_force(fn, vt, p[CLR_CF], p[CLR_FV0], p[CLR_FVM])
        fx = -fn * nx + ft * tx
        fy = -fn * ny + ft * ty
        _apply(g, bj, fx, fy, qjx, qjy, q)
        _apply(g, bi, -fx, -fy, qix, qiy, q)
    return fn, ft, vn, vt


@njit(cache=True, inline="always")
def _pos_t(q, b, c, s, sx, sy):
    """_pos with the body's cos c and sin s given (the same operations: r_b + (A_b s))."""
    if b < 0:
        return sx, sy
    rx, ry = c * sx - s * sy, s * sx + c * sy
    return q[3 * b] + rx, q[3 * b + 1] + ry


@njit(cache=True, inline="always")
def _cos_sin(q, b, cs, sn, trig):
    """cos and sin of body b's angle: from the workspace's cs, sn when ``trig`` (they hold them for q), else
    computed (1, 0 for the frame, b < 0, which needs none)."""
    if b < 0:
        return 1.0, 0.0
    if trig:
        return cs[b], sn[b]
    return math.cos(q[3 * b + 2]), math.sin(q[3 * b + 2])


@njit(cache=True, inline="always")
def eccentricity(q, bi, bj, p, cs, sn, trig):
    """Bearing centre (pix, piy), journal centre (pjx, pjy) and e = r_journal - r_bearing of a clearance
    joint with parameter row p (the one place r1 - r2 of the paper's eq. 1 is formed); ``trig`` as in
    :func:`_cos_sin`."""
    ci, si = _cos_sin(q, bi, cs, sn, trig)
    cj, sj = _cos_sin(q, bj, cs, sn, trig)
    pix, piy = _pos_t(q, bi, ci, si, p[CLR_SIX], p[CLR_SIY])
    pjx, pjy = _pos_t(q, bj, cj, sj, p[CLR_SJX], p[CLR_SJY])
    return pix, piy, pjx, pjy, pjx - pix, pjy - piy


@njit(cache=True, inline="always")
def _worn_zones(q, v, pair, p, tb, tj, gap, buf, g):
    """The contact forces of a worn joint (``pair``, its parameter row ``p``, the surface tables ``tb``, ``tj``
    of bearing and journal and its :class:`~wearbench.model.worn_contact.Gap` ``gap``) into g, the second
    zone's first (see :func:`clearance_forces`; ``buf``: the midpoint samples' work array); returns the top
    zone's direction and penetration, the summed normal and friction forces and its (vn, vt)."""
    top, second, sad = contact_zones(tb, tj, gap, p[CLR_CURV], buf)
    pen = top.overlap - gap.clear
    pen1 = pen
    fn2 = 0.0
    ft2 = 0.0
    if second.overlap > -math.inf:  # searched only in contact
        pen1, pen2, r = zone_penetrations(top.overlap, second.overlap, sad, gap.clear)
        fn2, ft2, _, _ = _zone_force(q, v, pair, p, math.cos(second.psi), math.sin(second.psi), pen2, second, r, g)
    fn, ft, vn, vt = _zone_force(q, v, pair, p, math.cos(top.psi), math.sin(top.psi), pen1, top, 1.0, g)
    return top.psi, pen, fn + fn2, ft + ft2, vn, vt


@njit(cache=True, inline="always")
def clearance_forces(q, v, mdl, cout, trig):
    """Add the clearance contact forces of the mechanism ``mdl`` (:class:`Model`: its parameters, contact
    modes and workspace) to W.g; fill cout (nc, NCO). ``trig``: W.cs and W.sn hold the bodies' cos/sin at q
    (inside :func:`accel`, after :func:`constraints`), else they are computed. The law is
    :func:`clearance_arrays`'s, on the record's parts."""
    clearance_arrays(q, v, mdl.P, mdl.W, mdl.inc, mdl.v0i, cout, trig)


@njit(cache=True, inline="always")
def clearance_arrays(q, v, P, W, inc, v0i, cout, trig):
    """:func:`clearance_forces` on the parts of the mechanism record (parameters P, workspace W, contact
    modes inc, v0i): for a caller that takes them from the record once for many evaluations.

    Geometry (paper eq. 1-6): e = journal centre - bearing centre, alpha = direction of e; new
    surfaces: penetration d = |e| - (R1 - R2) along alpha. Worn surfaces (JointSurfaces contract):
    d and the normal at the direction where the surfaces overlap most (``worn_contact.contact_zones``,
    from the surface tables ``P.surf_t``); the
    flag ``CLR_WORN`` keeps new surfaces on the even-clearance code path (bit-identical results).
    A worn joint may touch in two separate zones (a journal bridging a hollow on its two rims):
    a second local maximum of the overlap (the second zone) whose overlap f2 - c exceeds half
    the first's carries load too, each zone with its own normal and the joint's contact law. So
    the force stays continuous when two zones of nearly equal overlap trade places: the levels
    between the clearance c and the saddle s shared by both zones are split between them in
    proportion to their own heights above the saddle, pen_i = (f_i - S) + w_i (S - c),
    S = max(s, c), w_i = (f_i - S) / (f_1 + f_2 - 2 S); the second zone fades in smoothly
    (smoothstep) between overlap ratios 0.5 and 1 and the first zone's share blends with it.
    The record (cout) keeps the top zone's direction, penetration and speeds, and the summed
    normal and friction force magnitudes. Both surfaces go through one zone force (:func:`_zone_force`).
    ``inc[k]`` (contact flag) and ``v0i[k]`` (impact speed) are the mode state of joint k: while the flag
    is off the current normal speed stands in for the impact speed (contact onset).
    """
    clr_b, clr_p, surf_n, surf_t, g, buf, cs, sn = P.clr_b, P.clr_p, P.surf_n, P.surf_t, W.g, W.buf, W.cs, W.sn
    for k in range(clr_b.shape[0]):
        bi, bj = clr_b[k, 0], clr_b[k, 1]
        p = clr_p[k]
        pix, piy, pjx, pjy, ex, ey = eccentricity(q, bi, bj, p, cs, sn, trig)
        emag = math.sqrt(ex * ex + ey * ey)
        thi = 0.0 if bi < 0 else q[3 * bi + 2]
        thj = 0.0 if bj < 0 else q[3 * bj + 2]
        pair = Pair(bi=bi, bj=bj, pix=pix, piy=piy, pjx=pjx, pjy=pjy, wi=_omega(v, bi), wj=_omega(v, bj),
                    inc=inc[k], v0=v0i[k])
        if emag > 0.0:
            ux, uy = ex / emag, ey / emag
        else:  # journal exactly centred: any direction, no contact
            ux, uy = math.cos(thi), math.sin(thi)
        alpha = math.atan2(uy, ux)
        clear = p[CLR_R1] - p[CLR_R2]
        if p[CLR_WORN] > 0.0 and emag > 0.0:
            gap = Gap(nb=surf_n[k, 0], nj=surf_n[k, 1], emag=emag, alpha=alpha, thi=thi, thj=thj, clear=clear)
            psi, pen, fn, ft, vn, vt = _worn_zones(q, v, pair, p, surf_t[k, 0], surf_t[k, 1], gap, buf, g)
        else:
            psi, pen = alpha, emag - clear
            even = Zone(psi=psi, overlap=emag, hb=0.0, hj=0.0, slope_b=0.0, slope_j=0.0)  # no depths, no slopes
            fn, ft, vn, vt = _zone_force(q, v, pair, p, ux, uy, pen, even, 1.0, g)
        cout[k, CO_EX] = ex
        cout[k, CO_EY] = ey
        cout[k, CO_PEN] = pen
        cout[k, CO_FN] = fn
        cout[k, CO_FT] = ft
        cout[k, CO_VN] = vn
        cout[k, CO_VT] = vt
        cout[k, CO_OMEGA] = pair.wj - pair.wi
        cout[k, CO_PHIB] = (psi - thi) % (2.0 * math.pi)
        cout[k, CO_PHIJ] = (psi - thj) % (2.0 * math.pi)


@njit(cache=True, inline="always")
def element_forces(q, v, P, g):
    """Generalised forces of gravity, spring-dampers and applied torques (N, N m) into g."""
    fext, spr_b, spr_p, trq_b, trq_p = P.fext, P.spr_b, P.spr_p, P.trq_b, P.trq_p
    for i in range(g.shape[0]):
        g[i] = fext[i]
    for k in range(spr_b.shape[0]):
        bi, bj = spr_b[k, 0], spr_b[k, 1]
        p = spr_p[k]
        pix, piy = _pos(q, bi, p[0], p[1])
        pjx, pjy = _pos(q, bj, p[2], p[3])
        dx, dy = pjx - pix, pjy - piy
        length = math.sqrt(dx * dx + dy * dy)
        if length == 0.0:
            continue
        ux, uy = dx / length, dy / length
        vix, viy = _vel(q, v, bi, pix, piy)
        vjx, vjy = _vel(q, v, bj, pjx, pjy)
        rate = (vjx - vix) * ux + (vjy - viy) * uy
        f = p[4] * (length - p[6]) + p[5] * rate  # tension > 0 pulls the points together
        _apply(g, bi, f * ux, f * uy, pix, piy, q)
        _apply(g, bj, -f * ux, -f * uy, pjx, pjy, q)
    for k in range(trq_b.shape[0]):
        b = trq_b[k]
        g[3 * b + 2] += trq_p[k, 0] - trq_p[k, 1] * v[3 * b + 2]


@njit(cache=True, inline="always")
def schur(P, Jv, S):
    """S = Phi_q M^-1 Phi_q^T from the compact Jacobian: its lower triangle within the envelope (row k from
    column ``s_first[k]``), all that :func:`cholesky_solve` reads; the rest of S is left as it is."""
    minv, body_rows, body_nrows, first = P.minv, P.body_rows, P.body_nrows, P.s_first
    for k in range(S.shape[0]):
        for l in range(first[k], k + 1):
            S[k, l] = 0.0
    for b in range(body_nrows.shape[0]):
        mx, my, mt = minv[3 * b], minv[3 * b + 1], minv[3 * b + 2]
        nr = body_nrows[b]
        for x in range(nr):
            k, sk = body_rows[b, x, 0], body_rows[b, x, 1]
            # row k's entries times M^-1, formed once per row (the products' order is that of Jv M^-1 Jv^T)
            wx, wy, wt = Jv[k, sk, 0] * mx, Jv[k, sk, 1] * my, Jv[k, sk, 2] * mt
            for y in range(x, nr):
                l, sl = body_rows[b, y, 0], body_rows[b, y, 1]
                val = wx * Jv[l, sl, 0] + wy * Jv[l, sl, 1] + wt * Jv[l, sl, 2]
                S[max(k, l), min(k, l)] += val


@njit(cache=True, _nrt=False)
def cholesky_solve(S, rhs, x, first):
    """Solve S x = rhs in place (S's lower triangle overwritten by its Cholesky factor; the upper one is not
    read). Returns OK or SINGULAR.

    Only the envelope of S is worked on: row i's entries left of column ``first[i]`` are zero and
    stay zero in the factor, so the arithmetic on the rest is that of the dense factorisation
    (bit-identical results) without the products of zeros."""
    m = S.shape[0]
    scale = 0.0
    for i in range(m):
        scale = max(scale, S[i, i])
    tiny = 1e-13 * scale
    for j in range(m):
        fj = first[j]
        d = S[j, j]
        for p in range(fj, j):
            d -= S[j, p] * S[j, p]
        if not d > tiny:
            return SINGULAR
        d = math.sqrt(d)
        S[j, j] = d
        for i in range(j + 1, m):
            fi = first[i]
            if fi > j:
                continue
            s = S[i, j]
            for p in range(max(fi, fj), j):
                s -= S[i, p] * S[j, p]
            S[i, j] = s / d
    for i in range(m):
        s = rhs[i]
        for p in range(first[i], i):
            s -= S[i, p] * x[p]
        x[i] = s / S[i, i]
    for i in range(m - 1, -1, -1):
        s = x[i]
        for p in range(i + 1, m):
            if first[p] <= i:
                s -= S[p, i] * x[p]
        x[i] = s / S[i, i]
    return OK


@njit(cache=True, inline="always")
def _jt_times(P, Jv, lam, out):
    """out = Phi_q^T lam."""
    jb = P.jb
    _fill(out, 0.0)
    for k in range(jb.shape[0]):
        for s in range(2):
            b = jb[k, s]
            if b >= 0:
                out[3 * b] += Jv[k, s, 0] * lam[k]
                out[3 * b + 1] += Jv[k, s, 1] * lam[k]
                out[3 * b + 2] += Jv[k, s, 2] * lam[k]


@njit(cache=True, inline="always")
def _j_times(jb, Jv, x, k):
    """(Phi_q x)_k (``jb``: P.jb, taken from the record once by the caller, not once per row)."""
    s_ = 0.0
    for s in range(2):
        b = jb[k, s]
        if b >= 0:
            s_ += Jv[k, s, 0] * x[3 * b] + Jv[k, s, 1] * x[3 * b + 1] + Jv[k, s, 2] * x[3 * b + 2]
    return s_


@njit(cache=True, _nrt=False)
def accel(t, q, v, mdl, a, lam, cout):
    """Accelerations a (n) and multipliers lam (m) of eq. 30 for the mechanism ``mdl`` (:class:`Model`:
    parameters, motor speed, Baumgarte coefficients alpha, beta (0, 0 for none), contact modes and
    workspace) at (t, q, v); contact outputs into cout. Returns OK or SINGULAR. The equations are
    :func:`accel_arrays`'s, on the record's parts.
    """
    return accel_arrays(t, q, v, mdl.speed, mdl.P, mdl.W, (mdl.alpha, mdl.beta), mdl.inc, mdl.v0i, a, lam, cout)


@njit(cache=True, inline="always")
def accel_arrays(t, q, v, speed, P, W, stab, inc, v0i, a, lam, cout):
    """:func:`accel` on the parts of the mechanism record (motor speed, parameters P, workspace W,
    stab = (alpha, beta), contact modes inc, v0i), compiled into its caller: the integrators take the
    parts from the record once per step, not once per right-hand side (see :func:`clearance_arrays`)."""
    alpha, beta = stab
    minv, jb = P.minv, P.jb
    phi, Jv, gam, nu, g, S, rhs, tmp = W.phi, W.Jv, W.gam, W.nu, W.g, W.S, W.rhs, W.tmp
    constraints(t, q, v, speed, P, W)
    element_forces(q, v, P, g)
    clearance_arrays(q, v, P, W, inc, v0i, cout, True)
    m = phi.shape[0]
    n = q.shape[0]
    for i in range(n):
        tmp[i] = minv[i] * g[i]
    for k in range(m):
        r = gam[k]
        if alpha != 0.0 or beta != 0.0:
            r -= 2.0 * alpha * (_j_times(jb, Jv, v, k) - nu[k]) + beta * beta * phi[k]
        rhs[k] = _j_times(jb, Jv, tmp, k) - r
    if m > 0:
        schur(P, Jv, S)
        if cholesky_solve(S, rhs, lam, P.s_first) != OK:
            return SINGULAR
    _jt_times(P, Jv, lam, tmp)
    for i in range(n):
        a[i] = minv[i] * (g[i] - tmp[i])
    return OK


@njit(cache=True, _nrt=False)
def drift_of(P, v, W):
    """Largest position (m or rad) and velocity constraint violation (|Phi|_inf, |Phi_q v - nu|_inf)
    from the constraints already in the workspace W (evaluated at the state whose velocities are v)."""
    phi, Jv, nu, jb = W.phi, W.Jv, W.nu, P.jb
    dp = 0.0
    dv = 0.0
    for k in range(phi.shape[0]):
        dp = max(dp, abs(phi[k]))
        dv = max(dv, abs(_j_times(jb, Jv, v, k) - nu[k]))
    return dp, dv


@njit(cache=True, _nrt=False)
def drift(t, q, v, speed, P, W):
    """Largest position (m or rad) and velocity constraint violation: (|Phi|_inf, |Phi_q v - nu|_inf)."""
    constraints(t, q, v, speed, P, W)
    return drift_of(P, v, W)


@njit(cache=True, _nrt=False)
def project(t, q, v, speed, P, W, tol, maxit):
    """Project (q, v) onto Phi = 0 and Phi_q v = nu with the M-weighted minimum correction.

    Newton: dq = -M^-1 Phi_q^T S^-1 Phi until |Phi|_inf <= tol (m), then the same for velocities.
    For a fully driven mechanism (dof 0) this is the position and velocity analysis itself.
    Returns OK, SINGULAR or NO_CONVERGENCE.
    """
    minv, jb = P.minv, P.jb
    phi, Jv, nu, S, rhs, lam, tmp = W.phi, W.Jv, W.nu, W.S, W.rhs, W.lam, W.tmp
    m = phi.shape[0]
    if m == 0:
        return OK
    for it in range(maxit + 1):
        constraints(t, q, v, speed, P, W)
        err = 0.0
        for k in range(m):
            err = max(err, abs(phi[k]))
        if err <= tol:
            break
        if it == maxit:
            return NO_CONVERGENCE
        schur(P, Jv, S)
        for k in range(m):
            rhs[k] = phi[k]
        if cholesky_solve(S, rhs, lam, P.s_first) != OK:
            return SINGULAR
        _jt_times(P, Jv, lam, tmp)
        for i in range(q.shape[0]):
            q[i] -= minv[i] * tmp[i]
    schur(P, Jv, S)
    for k in range(m):
        rhs[k] = _j_times(jb, Jv, v, k) - nu[k]
    if cholesky_solve(S, rhs, lam, P.s_first) != OK:
        return SINGULAR
    _jt_times(P, Jv, lam, tmp)
    for i in range(v.shape[0]):
        v[i] -= minv[i] * tmp[i]
    return OK
