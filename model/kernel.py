"""Compiled core of the planar multibody model: constraints, forces, accelerations, projection.

Holds numba-compiled (``@njit(cache=True)``) functions on flat arrays; the scene (``scene.py``)
packs a mechanism into the named record ``P`` (:class:`Params`) described below and the integrators (``integrators.py``)
call :func:`accel` and :func:`project`. Imports numpy, numba and ``wearbench.model.contact`` only.

Coordinates: q = (x, y, theta) of each moving body's centre of mass (absolute coordinates), v = dq/dt.
Equations of motion (paper eq. 29-30) with a diagonal mass matrix M:
    M a + Phi_q^T lam = g,   Phi_q a = gamma - 2 alpha Phi' - beta^2 Phi,
solved through the Schur complement S = Phi_q M^-1 Phi_q^T (Cholesky, m x m). Each constraint row
touches at most two bodies, so Phi_q is stored compactly: body index ``Jb[k, s]`` (-1 = none) and
the three entries ``Jv[k, s, :]`` per slot s.

P = Params(minv, fext, rev_b, rev_s, pri_b, pri_s, drv_b, drv_p, clr_b, clr_p, surf, surf_n,
           spr_b, spr_p, trq_b, trq_p, jb, body_rows, body_nrows, profile), a named tuple numba compiles:
- minv (n,): inverse masses/inertias; fext (n,): constant generalised forces (gravity).
- rev_b (nr, 2), rev_s (nr, 4): ideal pin pairs: bodies (-1 = frame) and local points
  (x_i, y_i, x_j, y_j); constraint r_i + A_i s_i - r_j - A_j s_j = 0 (2 rows).
- pri_b (np, 2), pri_s (np, 5): prismatic joints: point s_j of body j on the line through s_i of
  body i with direction ``axis`` (in body i's frame); theta_j - theta_i = axis (2 rows).
- drv_b (nd,), drv_p (nd, 2): drivers theta_b = ratio * theta_motor(t) + phase (1 row).
- clr_b (nc, 2), clr_p (nc, NCLR): clearance joints (bearing body, journal body), see CLR_* below.
- surf (nc, 2, nmax), surf_n (nc, 2): worn depths of bearing [0] and journal [1], regions used.
- spr_b (ns, 2), spr_p (ns, 7): point-to-point spring-dampers (x_i, y_i, x_j, y_j, k, c, l0).
- trq_b (nt,), trq_p (nt, 2): applied torques T = T0 - c_rot * omega on a body.
- jb (m, 2): constant body pattern of Phi_q; body_rows (nb, kmax, 2), body_nrows (nb,): rows
  (row, slot) touching each body.
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
    depth_eval,
    friction_force,
    impact_speed,
    normal_force,
)

Params = namedtuple("Params", "minv fext rev_b rev_s pri_b pri_s drv_b drv_p clr_b clr_p surf surf_n "
                               "spr_b spr_p trq_b trq_p jb body_rows body_nrows profile")

# clearance parameter columns
CLR_SIX, CLR_SIY, CLR_SJX, CLR_SJY, CLR_R1, CLR_R2, CLR_K, CLR_N, CLR_CE, CLR_LAW, CLR_CF, \
    CLR_FV0, CLR_FVM, CLR_WORN = range(14)
NCLR = 14
# contact output columns (cout)
CO_EX, CO_EY, CO_PEN, CO_FN, CO_FT, CO_VN, CO_VT, CO_OMEGA, CO_PHIB, CO_PHIJ, CO_ALPHA = range(11)
NCO = 11

OK, SINGULAR, NO_CONVERGENCE = 0, 1, 2


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


@njit(cache=True)
def constraints(t, q, v, speed, P, phi, Jv, gam, nu):
    """Fill Phi (m), compact Phi_q values Jv (m, 2, 3), gamma (m) and nu = -Phi_t (m)."""
    rev_b, rev_s, pri_b, pri_s, drv_b, drv_p = P.rev_b, P.rev_s, P.pri_b, P.pri_s, P.drv_b, P.drv_p
    nb = q.shape[0] // 3
    cs = np.empty(nb)
    sn = np.empty(nb)
    for b in range(nb):
        cs[b] = math.cos(q[3 * b + 2])
        sn[b] = math.sin(q[3 * b + 2])
    Jv[:] = 0.0
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


@njit(cache=True)
def _overlap(sb, nb, sj, nj, emag, alpha, thi, thj, psi):
    """Radial overlap f(psi) = |e| cos(psi - alpha) - h_b(psi - th_b) - h_j(psi - th_j) (m) of the
    journal over the worn bearing in global direction ``psi``, with df/dpsi and d2f/dpsi2 and the
    two depths and slopes there (see :func:`worn_contact`)."""
    hb, db, d2b = depth_eval(sb, nb, psi - thi)
    hj, dj, d2j = depth_eval(sj, nj, psi - thj)
    c = math.cos(psi - alpha)
    s = math.sin(psi - alpha)
    return emag * c - hb - hj, -emag * s - db - dj, -emag * c - d2b - d2j, hb, hj, db, dj


@njit(cache=True)
def _node_min(depths, n, x0, x1):
    """Smallest node value of ``depths`` over the PCHIP intervals covering [x0, x1] (region units,
    centres at integers after the -0.5 shift): PCHIP never leaves the range of its two nodes, so
    this bounds the depth from below on the whole range."""
    i0 = math.floor(x0)
    i1 = math.floor(x1) + 1
    i = i0 % n
    lo = depths[i]
    for _ in range(i1 - i0):
        i = i + 1 if i + 1 < n else 0
        lo = min(lo, depths[i])
    return lo


@njit(cache=True, inline="always")
def _polish_peak(sb, nb, sj, nj, emag, alpha, thi, thj, psi, cell):
    """The local maximum of the overlap within ``cell`` of ``psi``: safeguarded Newton on f' = 0
    (bisects across a curvature jump)."""
    lo, hi = psi - cell, psi + cell
    for _ in range(24):
        d1, d2 = _overlap(sb, nb, sj, nj, emag, alpha, thi, thj, psi)[1:3]
        if d1 > 0.0:
            lo = psi
        else:
            hi = psi
        nxt = psi - d1 / d2 if d2 < 0.0 else 0.5 * (lo + hi)
        if not lo < nxt < hi:
            nxt = 0.5 * (lo + hi)
        if abs(nxt - psi) < 1e-13:
            break
        psi = nxt
    return psi


@njit(cache=True)
def worn_contact(sb, nb, sj, nj, emag, alpha, thi, thj, clear, hint):
    """Contact direction of a worn journal in a worn bearing: where the two surfaces overlap most.

    The journal (radius R2 - h_j, journal frame) reaches, in global direction psi from the bearing
    centre, |e| cos(psi - alpha) + R2 - h_j; the bearing wall is at R1 + h_b. The penetration is the
    largest overlap d = max_psi f(psi) - (R1 - R2), f as in :func:`_overlap` (the tangential offset
    of the journal centre adds (|e| sin)^2 / 2 R2 < 2e-8 m at 0.6 mm / 15 mm and is left out). So a
    circular (or worn) journal rests on the rims of a pit narrower than its relative curvature
    allows instead of sinking to its bottom, and by the envelope theorem grad_e d = u(psi*): the
    normal is the radial direction of the contact point, continuous while the maximum is unique.
    Search: climb from alpha (or from ``hint``, the last contact direction, if the overlap is larger
    there; a starting point only, the result does not depend on it) to a local maximum; then branch and bound outward from
    alpha over blocks of bearing intervals, while |e| cos(psi - alpha) can still beat the best
    overlap and the clearance: a block, then an interval, is looked at, and sampled, only if
    its upper bound |e| max cos - min node depths (PCHIP stays within its nodes) beats the best
    (at its middle);
    then Newton on f'(psi) = 0 around the best point.
    Returns (psi*, f(psi*), h_b, h_j, h_b', h_j') at the contact direction.
    """
    f0, d1, d2, hb0, hj0, sb0, sj0 = _overlap(sb, nb, sj, nj, emag, alpha, thi, thj, alpha)
    if emag <= max(f0, clear):
        return alpha, f0, hb0, hj0, sb0, sj0
    cell = 2.0 * math.pi / nb
    # 1. climb to the local maximum next to alpha (a good first bound prunes most of the scan)
    best, fbest = alpha, f0
    dh = (hint - alpha + math.pi) % (2.0 * math.pi) - math.pi
    if abs(dh) < 0.5 * math.pi:  # the last contact direction is usually next to this one
        fh, h1, h2 = _overlap(sb, nb, sj, nj, emag, alpha, thi, thj, alpha + dh)[:3]
        if fh > f0:
            best, fbest, d1, d2 = alpha + dh, fh, h1, h2
    walk = 0.5 * cell  # grows while f keeps rising where it is convex
    for it in range(30):
        if it >= 6 and fbest < clear:  # out of contact the scan prunes against the clearance anyway
            break
        if d2 < 0.0:
            stp = max(-cell, min(cell, -d1 / d2))
        else:
            stp = walk if d1 > 0.0 else -walk
            walk = min(2.0 * walk, 16.0 * cell)
        f, e1, e2 = _overlap(sb, nb, sj, nj, emag, alpha, thi, thj, best + stp)[:3]
        for _ in range(3):
            if f > fbest:
                break
            stp *= 0.25
            f, e1, e2 = _overlap(sb, nb, sj, nj, emag, alpha, thi, thj, best + stp)[:3]
        if f <= fbest:
            break
        best, fbest, d1, d2 = best + stp, f, e1, e2
        if abs(stp) < 1e-4 * cell:
            break
    # 2. branch and bound over blocks of bearing intervals, outward from alpha
    rj = nj / (2.0 * math.pi)
    ia = math.floor((alpha - thi) / cell - 0.5)
    blk = 8
    for sign in (-1, 1):
        first = ia if sign > 0 else ia - blk
        while True:
            lo_g = (first + 0.5) * cell + thi  # global angle of the block's first node
            hi_g = lo_g + blk * cell
            dmin = 0.0 if lo_g <= alpha <= hi_g else min(abs(lo_g - alpha), abs(hi_g - alpha))
            if dmin >= 0.5 * math.pi:
                break
            reach = emag * math.cos(dmin)
            floor = max(fbest, clear)
            if reach <= floor:
                break
            if reach - _node_min(sb, nb, first, first + blk) - _node_min(
                    sj, nj, (lo_g - thj) * rj - 0.5, (hi_g - thj) * rj - 0.5) > floor:
                for i in range(first, first + blk):
                    lo_b = (i + 0.5) * cell + thi
                    hi_b = lo_b + cell
                    d = 0.0 if lo_b <= alpha <= hi_b else min(abs(lo_b - alpha), abs(hi_b - alpha))
                    bound = emag * math.cos(d) - min(sb[i % nb], sb[(i + 1) % nb]) - _node_min(
                        sj, nj, (lo_b - thj) * rj - 0.5, (hi_b - thj) * rj - 0.5)
                    if bound > max(fbest, clear):
                        psi = lo_b + 0.5 * cell
                        f = _overlap(sb, nb, sj, nj, emag, alpha, thi, thj, psi)[0]
                        if f > fbest:
                            best, fbest = psi, f
            first += sign * blk
    if fbest < clear - 1e-6:  # no contact by a wide margin: its exact place does not matter
        f, _, _, hb, hj, db, dj = _overlap(sb, nb, sj, nj, emag, alpha, thi, thj, best)
        return best, f, hb, hj, db, dj
    psi = _polish_peak(sb, nb, sj, nj, emag, alpha, thi, thj, best, cell)
    f, _, _, hb, hj, db, dj = _overlap(sb, nb, sj, nj, emag, alpha, thi, thj, psi)
    if f < fbest:  # Newton left the best sample's value behind (flat cell): keep the sample
        psi = best
        f, _, _, hb, hj, db, dj = _overlap(sb, nb, sj, nj, emag, alpha, thi, thj, psi)
    return psi, f, hb, hj, db, dj


SECOND_ZONE_RATIO = 0.5  # a second zone counts once its overlap exceeds this fraction of the first's


@njit(cache=True)
def second_zone(sb, nb, sj, nj, emag, alpha, thi, thj, clear, psi1, f1):
    """The second contact zone of a worn joint: the highest local maximum of the overlap f (see
    :func:`_overlap`) other than the top one (psi1, f1), and the lowest overlap between the two.

    Walks outward from psi1 over bearing-interval midpoints on both sides, through valleys and
    over peaks, while |e| cos can still reach the floor clear + SECOND_ZONE_RATIO (f1 - clear),
    skipping blocks of 8 intervals whose upper bound (|e| max cos - min node depths) cannot reach
    the clearance; the highest peak above the floor is polished by safeguarded Newton (it may
    equal f1: two zones of equal overlap). Returns (psi2, f2, s) with
    f2 = -inf when there is no second zone above the floor; s is the lowest sampled overlap on the
    way from psi1 to psi2 (the saddle, from the interval midpoints; continuous in the state, as a
    minimum of continuous samples, and never below the true saddle).
    """
    floor = clear + SECOND_ZONE_RATIO * (f1 - clear)
    if emag <= floor:
        return psi1, -math.inf, -math.inf
    cell = 2.0 * math.pi / nb
    rj = nj / (2.0 * math.pi)
    i1 = math.floor((psi1 - thi) / cell - 0.5)  # bearing interval holding psi1
    best_psi, best_f, best_s = psi1, -math.inf, -math.inf
    for sign in (-1, 1):
        valley = f1
        prev, prev_psi = f1, psi1
        rising = False
        i = i1 + sign
        while abs(i - i1) <= nb // 2:
            mid = (i + 1.0) * cell + thi
            dm = abs((mid - alpha + math.pi) % (2.0 * math.pi) - math.pi)
            if dm >= 0.5 * math.pi or emag * math.cos(max(0.0, dm - 8.0 * cell)) <= floor:
                break
            # block bound: can any of the next 8 intervals overlap at all? (if not, the saddle
            # between zones on either side is below the clearance, which is all that matters)
            j0 = i if sign > 0 else i - 7
            lo_g = (j0 + 0.5) * cell + thi
            if emag * math.cos(max(0.0, dm - 8.0 * cell)) - _node_min(sb, nb, j0, j0 + 8) - _node_min(
                    sj, nj, (lo_g - thj) * rj - 0.5, (lo_g + 8 * cell - thj) * rj - 0.5) <= clear:
                if rising and prev > best_f:  # the peak was the last sample before the gap
                    best_psi, best_f, best_s = prev_psi, prev, valley
                valley = min(valley, clear)
                prev, prev_psi = -math.inf, mid
                rising = False
                i += 8 * sign
                continue
            f = _overlap(sb, nb, sj, nj, emag, alpha, thi, thj, mid)[0]
            if f < prev:
                if rising and prev > best_f:  # passed a peak at the previous sample
                    best_psi, best_f, best_s = prev_psi, prev, valley
                rising = False
                valley = min(valley, f)
            elif f > prev:
                rising = True
            prev, prev_psi = f, mid
            i += sign
        if rising and prev > best_f:
            best_psi, best_f, best_s = prev_psi, prev, valley
    if best_f <= floor:
        return psi1, -math.inf, -math.inf
    psi = _polish_peak(sb, nb, sj, nj, emag, alpha, thi, thj, best_psi, cell)
    f = _overlap(sb, nb, sj, nj, emag, alpha, thi, thj, psi)[0]
    if f < best_f:
        psi, f = best_psi, best_f
    if abs((psi - psi1 + math.pi) % (2.0 * math.pi) - math.pi) < cell:
        return psi1, -math.inf, -math.inf  # climbed back into the top zone
    return psi, f, min(best_s, f)


@njit(cache=True)
def zone_penetrations(f1, f2, sad, clear):
    """Penetrations (m) of two contact zones with peak overlaps f1 >= f2 > clear and saddle
    overlap ``sad`` between them, and the weight r in [0, 1] of the second zone's force.

    The levels between the clearance c and S = max(sad, c), shared by both zones, are split in
    proportion to their heights above S: pen_i = (f_i - S) + w_i (S - c), w_i = (f_i - S) /
    (f1 + f2 - 2 S), symmetric when the zones trade places, pen2 -> 0 when the second peak merges
    into the first (f2 -> sad). The second zone fades in (smoothstep r) as (f2 - c) / (f1 - c)
    rises from SECOND_ZONE_RATIO to 1, and the first zone's penetration blends back to f1 - c as
    r -> 0: every quantity is continuous in (f1, f2, sad)."""
    x = ((f2 - clear) / (f1 - clear) - SECOND_ZONE_RATIO) / (1.0 - SECOND_ZONE_RATIO)
    x = min(1.0, max(0.0, x))
    r = x * x * (3.0 - 2.0 * x)
    top = max(sad, clear)
    a1, a2 = f1 - top, f2 - top
    w2 = a2 / (a1 + a2) if a1 + a2 > 0.0 else 0.5
    return f1 - clear - r * w2 * (top - clear), a2 + w2 * (top - clear), r


@njit(cache=True)
def _zone_force(q, v, bi, bj, p, pix, piy, pjx, pjy, wi, wj, psi, pen, hb, hj, slope_b, slope_j,
                inck, v0k, scale, g):
    """Apply the normal and friction force of one contact zone (direction psi, penetration pen,
    force scaled by ``scale`` in [0, 1]); returns (fn, ft, vn, vt)."""
    nx, ny = math.cos(psi), math.sin(psi)
    tx, ty = -ny, nx
    qix, qiy = pix + (p[CLR_R1] + hb) * nx, piy + (p[CLR_R1] + hb) * ny
    qjx, qjy = pjx + (p[CLR_R2] - hj) * nx, pjy + (p[CLR_R2] - hj) * ny
    vix, viy = _vel(q, v, bi, qix, qiy)
    vjx, vjy = _vel(q, v, bj, qjx, qjy)
    cix, ciy = _vel(q, v, bi, pix, piy)
    cjx, cjy = _vel(q, v, bj, pjx, pjy)
    vn = nx * (cjx - cix) + ny * (cjy - ciy) + slope_b * wi + slope_j * wj
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


@njit(cache=True)
def clearance_forces(q, v, P, inc, v0i, g, cout):
    """Add the clearance contact forces to g; fill cout (nc, NCO).

    Geometry (paper eq. 1-6): e = journal centre - bearing centre, alpha = direction of e; new
    surfaces: penetration d = |e| - (R1 - R2) along alpha. Worn surfaces (JointSurfaces contract):
    d and the normal at the direction where the surfaces overlap most (:func:`worn_contact`); the
    flag ``CLR_WORN`` keeps new surfaces on the even-clearance code path (bit-identical results).
    A worn joint may touch in two separate zones (a journal bridging a hollow on its two rims):
    a second local maximum of the overlap (:func:`second_zone`) whose overlap f2 - c exceeds half
    the first's carries load too, each zone with its own normal and the joint's contact law. So
    the force stays continuous when two zones of nearly equal overlap trade places: the levels
    between the clearance c and the saddle s shared by both zones are split between them in
    proportion to their own heights above the saddle, pen_i = (f_i - S) + w_i (S - c),
    S = max(s, c), w_i = (f_i - S) / (f_1 + f_2 - 2 S); the second zone fades in smoothly
    (smoothstep) between overlap ratios 0.5 and 1 and the first zone's share blends with it.
    The record (cout) keeps the top zone's direction, penetration and speeds, and the summed
    normal and friction force magnitudes.
    ``inc[k]`` (contact flag) and ``v0i[k]`` (impact speed) are the mode state of joint k: while
    the flag is off the current normal speed stands in for the impact speed (contact onset).
    """
    clr_b, clr_p, surf, surf_n = P.clr_b, P.clr_p, P.surf, P.surf_n
    for k in range(clr_b.shape[0]):
        bi, bj = clr_b[k, 0], clr_b[k, 1]
        p = clr_p[k]
        pix, piy = _pos(q, bi, p[CLR_SIX], p[CLR_SIY])
        pjx, pjy = _pos(q, bj, p[CLR_SJX], p[CLR_SJY])
        ex, ey = pjx - pix, pjy - piy
        emag = math.sqrt(ex * ex + ey * ey)
        thi = 0.0 if bi < 0 else q[3 * bi + 2]
        thj = 0.0 if bj < 0 else q[3 * bj + 2]
        wi, wj = _omega(v, bi), _omega(v, bj)
        if emag > 0.0:
            ux, uy = ex / emag, ey / emag
        else:  # journal exactly centred: any direction, no contact
            ux, uy = math.cos(thi), math.sin(thi)
        alpha = math.atan2(uy, ux)
        clear = p[CLR_R1] - p[CLR_R2]
        psi = alpha
        pen = emag - clear
        if p[CLR_WORN] > 0.0 and emag > 0.0:
            psi, overlap, hb, hj, slope_b, slope_j = worn_contact(
                surf[k, 0], surf_n[k, 0], surf[k, 1], surf_n[k, 1], emag, alpha, thi, thj, clear,
                cout[k, CO_ALPHA])
            pen = overlap - clear
            pen1 = pen
            fn2 = 0.0
            ft2 = 0.0
            if pen > 0.0:
                psi2, f2, sad = second_zone(surf[k, 0], surf_n[k, 0], surf[k, 1], surf_n[k, 1], emag,
                                            alpha, thi, thj, clear, psi, overlap)
                if f2 > -math.inf:
                    pen1, pen2, r = zone_penetrations(overlap, f2, sad, clear)
                    _, _, _, hb2, hj2, sb2, sj2 = _overlap(surf[k, 0], surf_n[k, 0], surf[k, 1],
                                                           surf_n[k, 1], emag, alpha, thi, thj, psi2)
                    fn2, ft2, _, _ = _zone_force(q, v, bi, bj, p, pix, piy, pjx, pjy, wi, wj, psi2,
                                                 pen2, hb2, hj2, sb2, sj2, inc[k], v0i[k], r, g)
            fn, ft, vn, vt = _zone_force(q, v, bi, bj, p, pix, piy, pjx, pjy, wi, wj, psi, pen1, hb,
                                         hj, slope_b, slope_j, inc[k], v0i[k], 1.0, g)
            fn += fn2
            ft += ft2
        else:
            nx, ny = ux, uy
            tx, ty = -ny, nx
            # contact points on each body and their material velocities
            qix, qiy = pix + p[CLR_R1] * nx, piy + p[CLR_R1] * ny
            qjx, qjy = pjx + p[CLR_R2] * nx, pjy + p[CLR_R2] * ny
            vix, viy = _vel(q, v, bi, qix, qiy)
            vjx, vjy = _vel(q, v, bj, qjx, qjy)
            # centre velocities give the rate of the penetration (rolling terms are tangential)
            cix, ciy = _vel(q, v, bi, pix, piy)
            cjx, cjy = _vel(q, v, bj, pjx, pjy)
            dex, dey = cjx - cix, cjy - ciy
            vn = ux * dex + uy * dey
            vt = (vjx - vix) * tx + (vjy - viy) * ty
            fn = 0.0
            ft = 0.0
            if pen > 0.0:
                v0 = v0i[k] if inc[k] != 0 else impact_speed(vn)
                fn = normal_force(pen, vn, p[CLR_K], p[CLR_N], p[CLR_CE], v0, int(p[CLR_LAW]))
                ft = friction_force(fn, vt, p[CLR_CF], p[CLR_FV0], p[CLR_FVM])
                fx = -fn * nx + ft * tx
                fy = -fn * ny + ft * ty
                _apply(g, bj, fx, fy, qjx, qjy, q)
                _apply(g, bi, -fx, -fy, qix, qiy, q)
        c = cout[k]
        c[CO_EX] = ex
        c[CO_EY] = ey
        c[CO_PEN] = pen
        c[CO_FN] = fn
        c[CO_FT] = ft
        c[CO_VN] = vn
        c[CO_VT] = vt
        c[CO_OMEGA] = wj - wi
        c[CO_PHIB] = (psi - thi) % (2.0 * math.pi)
        c[CO_PHIJ] = (psi - thj) % (2.0 * math.pi)
        c[CO_ALPHA] = psi


@njit(cache=True)
def element_forces(q, v, P, g):
    """Generalised forces of gravity, spring-dampers and applied torques (N, N m) into g."""
    fext, spr_b, spr_p, trq_b, trq_p = P.fext, P.spr_b, P.spr_p, P.trq_b, P.trq_p
    g[:] = fext
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


@njit(cache=True)
def _schur(P, Jv, S):
    """S = Phi_q M^-1 Phi_q^T from the compact Jacobian."""
    minv, body_rows, body_nrows = P.minv, P.body_rows, P.body_nrows
    S[:] = 0.0
    for b in range(body_nrows.shape[0]):
        mx, my, mt = minv[3 * b], minv[3 * b + 1], minv[3 * b + 2]
        nr = body_nrows[b]
        for x in range(nr):
            k, sk = body_rows[b, x, 0], body_rows[b, x, 1]
            for y in range(x, nr):
                l, sl = body_rows[b, y, 0], body_rows[b, y, 1]
                val = (Jv[k, sk, 0] * mx * Jv[l, sl, 0] + Jv[k, sk, 1] * my * Jv[l, sl, 1]
                       + Jv[k, sk, 2] * mt * Jv[l, sl, 2])
                S[k, l] += val
                if l != k:
                    S[l, k] += val


@njit(cache=True)
def _cholesky_solve(S, rhs, x):
    """Solve S x = rhs in place (S overwritten by its Cholesky factor). Returns OK or SINGULAR."""
    m = S.shape[0]
    scale = 0.0
    for i in range(m):
        scale = max(scale, S[i, i])
    tiny = 1e-13 * scale
    for j in range(m):
        d = S[j, j]
        for p in range(j):
            d -= S[j, p] * S[j, p]
        if not d > tiny:
            return SINGULAR
        d = math.sqrt(d)
        S[j, j] = d
        for i in range(j + 1, m):
            s = S[i, j]
            for p in range(j):
                s -= S[i, p] * S[j, p]
            S[i, j] = s / d
    for i in range(m):
        s = rhs[i]
        for p in range(i):
            s -= S[i, p] * x[p]
        x[i] = s / S[i, i]
    for i in range(m - 1, -1, -1):
        s = x[i]
        for p in range(i + 1, m):
            s -= S[p, i] * x[p]
        x[i] = s / S[i, i]
    return OK


@njit(cache=True, inline="always")
def _jt_times(P, Jv, lam, out):
    """out = Phi_q^T lam."""
    jb = P.jb
    out[:] = 0.0
    for k in range(jb.shape[0]):
        for s in range(2):
            b = jb[k, s]
            if b >= 0:
                out[3 * b] += Jv[k, s, 0] * lam[k]
                out[3 * b + 1] += Jv[k, s, 1] * lam[k]
                out[3 * b + 2] += Jv[k, s, 2] * lam[k]


@njit(cache=True, inline="always")
def _j_times(P, Jv, x, k):
    """(Phi_q x)_k."""
    jb = P.jb
    s_ = 0.0
    for s in range(2):
        b = jb[k, s]
        if b >= 0:
            s_ += Jv[k, s, 0] * x[3 * b] + Jv[k, s, 1] * x[3 * b + 1] + Jv[k, s, 2] * x[3 * b + 2]
    return s_


@njit(cache=True)
def accel(t, q, v, speed, P, alpha, beta, inc, v0i, a, lam, cout, W):
    """Accelerations a (n) and multipliers lam (m) of eq. 30; contact outputs into cout.

    alpha, beta: Baumgarte coefficients (0, 0 for none). W: work arrays (phi, Jv, gam, nu, g, S, rhs, tmp).
    Returns OK or SINGULAR.
    """
    minv = P.minv
    phi, Jv, gam, nu, g, S, rhs, tmp = W
    constraints(t, q, v, speed, P, phi, Jv, gam, nu)
    element_forces(q, v, P, g)
    clearance_forces(q, v, P, inc, v0i, g, cout)
    m = phi.shape[0]
    n = q.shape[0]
    for i in range(n):
        tmp[i] = minv[i] * g[i]
    for k in range(m):
        r = gam[k]
        if alpha != 0.0 or beta != 0.0:
            r -= 2.0 * alpha * (_j_times(P, Jv, v, k) - nu[k]) + beta * beta * phi[k]
        rhs[k] = _j_times(P, Jv, tmp, k) - r
    if m > 0:
        _schur(P, Jv, S)
        if _cholesky_solve(S, rhs, lam) != OK:
            return SINGULAR
    _jt_times(P, Jv, lam, tmp)
    for i in range(n):
        a[i] = minv[i] * (g[i] - tmp[i])
    return OK


@njit(cache=True)
def drift(t, q, v, speed, P, W):
    """Largest position (m or rad) and velocity constraint violation: (|Phi|_inf, |Phi_q v - nu|_inf)."""
    phi, Jv, gam, nu = W[0], W[1], W[2], W[3]
    constraints(t, q, v, speed, P, phi, Jv, gam, nu)
    dp = 0.0
    dv = 0.0
    for k in range(phi.shape[0]):
        dp = max(dp, abs(phi[k]))
        dv = max(dv, abs(_j_times(P, Jv, v, k) - nu[k]))
    return dp, dv


@njit(cache=True)
def project(t, q, v, speed, P, W, tol, maxit):
    """Project (q, v) onto Phi = 0 and Phi_q v = nu with the M-weighted minimum correction.

    Newton: dq = -M^-1 Phi_q^T S^-1 Phi until |Phi|_inf <= tol (m), then the same for velocities.
    For a fully driven mechanism (dof 0) this is the position and velocity analysis itself.
    Returns OK, SINGULAR or NO_CONVERGENCE.
    """
    minv = P.minv
    phi, Jv, gam, nu, _, S, rhs, tmp = W
    m = phi.shape[0]
    if m == 0:
        return OK
    lam = np.empty(m)
    for it in range(maxit + 1):
        constraints(t, q, v, speed, P, phi, Jv, gam, nu)
        err = 0.0
        for k in range(m):
            err = max(err, abs(phi[k]))
        if err <= tol:
            break
        if it == maxit:
            return NO_CONVERGENCE
        _schur(P, Jv, S)
        for k in range(m):
            rhs[k] = phi[k]
        if _cholesky_solve(S, rhs, lam) != OK:
            return SINGULAR
        _jt_times(P, Jv, lam, tmp)
        for i in range(q.shape[0]):
            q[i] -= minv[i] * tmp[i]
    _schur(P, Jv, S)
    for k in range(m):
        rhs[k] = _j_times(P, Jv, v, k) - nu[k]
    if _cholesky_solve(S, rhs, lam) != OK:
        return SINGULAR
    _jt_times(P, Jv, lam, tmp)
    for i in range(v.shape[0]):
        v[i] -= minv[i] * tmp[i]
    return OK
