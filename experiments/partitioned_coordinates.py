"""Partitioned (independent) coordinates against the augmented solve on the test bed (issue 27).

Issue 27 asked whether "independent or partitioned coordinates for a closed-loop mechanism instead of
a dense augmented solve per evaluation" would make a realisation cheaper. This script measures it
without touching ``model/`` (it calls the compiled kernels of ``wearbench.model.kernel``: constraints,
force elements, contact forces). Measured: 0.99x / 1.12x per evaluation against the augmented solve,
the same steps: not a route to the speed-up, so it lives here, an experiment no test run loads
(``experiments/test_partitioned_coordinates.py`` checks it when run by hand: ``.venv/bin/pytest experiments``).

The right-hand side in partitioned coordinates (Wehage-Haug): the 4 independent coordinates q_v are
the columns left over by an LU with complete pivoting of Phi_q (20 x 24) at the start state; the 20
dependent ones q_u follow from Phi(q_u, q_v, t) = 0 by Newton, started from the last solution moved
along the last velocity transformation (q_u + R_u dq_v + s_u dt) and iterated with the last call's
factorisation of Phi_u (frozen: a modified Newton); then Phi_u is factorised at the solution (a sparse
LU in a fixed threshold-Markowitz order, its fill pattern found once per partition), R_u = -Phi_u^-1
Phi_v, v_u = R_u v_v + Phi_u^-1 nu, c_u = Phi_u^-1 gamma (gamma at the exact velocities: the constraints
evaluated a second time), the reduced equations (R^T M R) a_v = R^T (g - M c) (4 x 4, Cholesky) and
a_u = R_u a_v + c_u. When a pivot falls below ``MIN_PIVOT`` of its value at the partition the block is
re-partitioned (new independent set and order).

What it prints, on the test bed (0.3 mm, nominal) on new and 400,000-cycle worn surfaces:
1. the check: the 24 accelerations against ``kernel.accel`` at the partitioned method's own state, at
   every 20 kHz sample of one default revolution (the samples projected onto the constraints first,
   then visited in order, so Newton starts from the previous sample's solution);
2. the cost of one evaluation of each (compiled loops over the same states, interleaved, best of
   ``--repeat``, CPU time) and the partitioned one part by part (each part timed alone on the same
   states: constraints, a substitution, the factorisation, the forces, the reduced system; Newton's
   count per call is the check's);
3. ``--revolutions`` (3) revolutions with DOPRI5 (the default's tableau and PI step control, same tolerances) on the
   8-component reduced state against ``simulate`` (default method), both from the same projected start:
   accepted / rejected steps, evaluations, CPU, and the slider acceleration's RMS error over the first
   20 and 40 ms against a tight reference (rtol 1e-10), for both, and of the one against the other.

Run:  .venv/bin/python experiments/partitioned_coordinates.py [--repeat 3] [--states new worn]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections import namedtuple
from pathlib import Path

import numpy as np
from numba import njit
from wearbench.model import integrators as I
from wearbench.model import kernel as K
from wearbench.model.contact import impact_speed
from wearbench.model.scene import dense_jacobian

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository: the profile's clock and loop watch
from benchmarks.model.profile_revolution import clock, contact_modes, watched_loop

STATES = {"new": "0.3 mm new", "worn": "0.3 mm second wear"}
NEWTON_TOL = 1e-12  # m (or rad): largest |Phi| the position solve leaves
NEWTON_MAXIT = 8
MIN_PIVOT = 0.1  # re-partition when a pivot of Phi_u falls below this share of its value at the partition
MARKOWITZ_U = 0.1  # threshold pivoting: a pivot at least this share of its column's largest entry
OK, NO_CONVERGENCE, REPARTITION = 0, 2, 3

# the partition: dependent coordinates in pivot order (dep), independent ones (indep), each
# coordinate's pivot position (>= 0) or -(1 + independent index) (colpos), each constraint row's
# pivot position (rowpos), the fill pattern of L by columns (lptr, lidx) and of U by rows (uptr, uidx),
# the fill entries to clear before loading (zidx: flat indices), |pivots| at the partition (piv0), masses, the
# structural non-zeros of the compact Jacobian as (row, slot, component, pivot row, pivot column) into Phi_u
# (amap) and (row, slot, component, pivot row, independent index) into Phi_v (vmap)
Partition = namedtuple("Partition", "dep indep colpos rowpos lptr lidx uptr uidx zidx piv0 mass min_pivot amap vmap")
# the reduced method's work arrays: the full q, v, a; LU of Phi_u (A) and Phi_v (V) in pivot order;
# [R_u | s_u] (m x 5: the velocity transformation and Phi_u^-1 nu), c_u; a substitution vector; the reduced system; the last solution (qlast, qvlast, tlast);
# flags (have[0]: a last solution); counts: calls, Newton updates,
# constraint evaluations, failures, Newton updates with a fresh factorisation
Reduced = namedtuple("Reduced", "q v a A V Ru cu x Mr fr av qlast qvlast tlast have counts")


# --- the partition (numpy, once per partition) ---------------------------------------------------------------

def _pattern(scene, t: float, q: np.ndarray, v: np.ndarray, speed: float) -> np.ndarray:
    """Structural non-zeros of Phi_q: the union over the state and four states with random angles."""
    P, W, n = scene.params, scene.work(), scene.n
    rng = np.random.default_rng(0)
    pat = np.zeros((scene.m, n), bool)
    for r in range(5):
        qq = q.copy()
        if r:
            qq[2::3] += rng.uniform(-math.pi, math.pi, n // 3)
        K.constraints(t, qq, v.copy(), speed, P, W)
        pat |= dense_jacobian(P, W.Jv, n) != 0.0
    return pat


def choose_partition(scene, t: float, q: np.ndarray, v: np.ndarray, speed: float) -> Partition:
    """Independent coordinates from an LU with complete pivoting of Phi_q at (t, q); a static pivot order
    of the dependent block Phi_u by threshold Markowitz (sparse and stable at this state) and its fill."""
    P, W, n, m = scene.params, scene.work(), scene.n, scene.m
    K.constraints(t, q.copy(), v.copy(), speed, P, W)
    J = dense_jacobian(P, W.Jv, n)
    A, cols = J.copy(), np.arange(n)
    for k in range(m):
        i, j = np.unravel_index(np.argmax(np.abs(A[k:, k:])), (m - k, n - k))
        i, j = i + k, j + k
        A[[k, i]] = A[[i, k]]
        A[:, [k, j]] = A[:, [j, k]]
        cols[[k, j]] = cols[[j, k]]
        A[k + 1:, k:] -= np.outer(A[k + 1:, k] / A[k, k], A[k, k:])
    dep_set, indep = np.sort(cols[:m]), np.sort(cols[m:])
    B = J[:, dep_set].copy()
    S = _pattern(scene, t, q, v, speed)[:, dep_set]
    rows, cols_left, prow, pcol = list(range(m)), list(range(m)), [], []
    for _ in range(m):
        best = None
        for j in cols_left:
            colmax = max(abs(B[i, j]) for i in rows)
            cc = sum(S[i, j] for i in rows)
            for i in rows:
                if S[i, j] and abs(B[i, j]) >= MARKOWITZ_U * colmax and B[i, j] != 0.0:
                    key = ((sum(S[i, c] for c in cols_left) - 1) * (cc - 1), -abs(B[i, j]))
                    if best is None or key < best[0]:
                        best = (key, i, j)
        _, i, j = best
        prow.append(i)
        pcol.append(j)
        rows.remove(i)
        cols_left.remove(j)
        for r in rows:
            if S[r, j]:
                f = B[r, j] / B[i, j]
                for c in cols_left:
                    if S[i, c]:
                        B[r, c] -= f * B[i, c]
                        S[r, c] = True
    Bp = J[:, dep_set][prow][:, pcol]
    F = _pattern(scene, t, q, v, speed)[:, dep_set][prow][:, pcol]
    U = Bp.copy()
    for k in range(m):  # symbolic fill and the pivots at the partition (no pivoting: the order is fixed)
        for i in range(k + 1, m):
            if F[i, k]:
                f = U[i, k] / U[k, k]
                for j in range(k + 1, m):
                    if F[k, j]:
                        F[i, j] = True
                        U[i, j] -= f * U[k, j]
    lists_l = [[i for i in range(k + 1, m) if F[i, k]] for k in range(m)]
    lists_u = [[j for j in range(k + 1, m) if F[k, j]] for k in range(m)]
    dep = dep_set[pcol]
    colpos = np.empty(n, np.int64)
    colpos[dep] = np.arange(m)
    colpos[indep] = -1 - np.arange(indep.size)
    rowpos = np.empty(m, np.int64)
    rowpos[prow] = np.arange(m)

    def flat(lists):
        return np.cumsum([0] + [len(x) for x in lists]).astype(np.int64), np.array([i for x in lists for i in x], np.int64)

    lptr, lidx = flat(lists_l)
    uptr, uidx = flat(lists_u)
    pat = _pattern(scene, t, q, v, speed)
    amap, vmap = [], []
    for k in range(m):
        for s in range(2):
            b = P.jb[k, s]
            for c in range(3 if b >= 0 else 0):
                if pat[k, 3 * b + c]:
                    p = colpos[3 * b + c]
                    (amap if p >= 0 else vmap).append((k, s, c, rowpos[k], p if p >= 0 else -1 - p))
    Fp = np.zeros((m, m), bool)  # the entries loaded: the rest of the fill pattern is cleared before each load
    for _, _, _, r, p in amap:
        Fp[r, p] = True
    zidx = np.flatnonzero(F & ~Fp).astype(np.int64)
    return Partition(dep.astype(np.int64), indep.astype(np.int64), colpos, rowpos, lptr, lidx, uptr, uidx, zidx,
                     np.abs(np.diag(U)), 1.0 / P.minv, MIN_PIVOT, np.array(amap, np.int64).reshape(-1, 5),
                     np.array(vmap, np.int64).reshape(-1, 5))


@njit(cache=True)
def _factor(part, Jv, A, V):
    return load_factor(part.zidx, part.amap, part.vmap, part.lptr, part.lidx, part.uptr, part.uidx, part.piv0, Jv,
                       A, V)


def new_reduced(scene, part: Partition, t: float, q: np.ndarray, v: np.ndarray, speed: float) -> Reduced:
    """Work arrays of the reduced method seeded with the state (t, q, v) (its q_u the first Newton start,
    Phi_u factorised there)."""
    n, m, nv = scene.n, scene.m, part.indep.size
    Z = Reduced(q.copy(), v.copy(), np.zeros(n), np.zeros((m, m)), np.zeros((m, nv)), np.zeros((m, nv + 1)),
                np.zeros(m), np.zeros(m), np.zeros((nv, nv)), np.zeros(nv), np.zeros(nv), q.copy(),
                q[part.indep].copy(), np.array([t]), np.zeros(1, np.int64), np.zeros(5, np.int64))
    W = scene.work()
    K.constraints(t, Z.q, Z.v, speed, scene.params, W)
    _factor(part, W.Jv, Z.A, Z.V)
    return Z


# --- the compiled reduced right-hand side ---------------------------------------------------------------------

# The helpers take plain arrays: a named tuple of arrays passed into an inlined function costs an atomic
# reference count increment and decrement per array (~0.6 us per call for the four tuples here).

@njit(cache=True, inline="always")
def load_factor(zidx, amap, vmap, lptr, lidx, uptr, uidx, piv0, Jv, A, V):
    """Phi_u (pivot order) into A and Phi_v into V from the compact Jacobian, then A's LU in place in the
    partition's fixed order (only the fill pattern worked on; the diagonal keeps the reciprocal pivots).
    Returns the smallest |pivot| as a share of its value at the partition (0 for a zero pivot)."""
    m = A.shape[0]
    for x in range(zidx.shape[0]):
        z = zidx[x]
        A[z // m, z % m] = 0.0
    for x in range(amap.shape[0]):
        A[amap[x, 3], amap[x, 4]] = Jv[amap[x, 0], amap[x, 1], amap[x, 2]]
    for x in range(vmap.shape[0]):
        V[vmap[x, 3], vmap[x, 4]] = Jv[vmap[x, 0], vmap[x, 1], vmap[x, 2]]
    worst = math.inf
    for k in range(m):
        piv = A[k, k]
        if piv == 0.0:
            return 0.0
        worst = min(worst, abs(piv) / piv0[k])
        inv = 1.0 / piv
        A[k, k] = inv
        for x in range(lptr[k], lptr[k + 1]):
            i = lidx[x]
            f = A[i, k] * inv
            A[i, k] = f
            for y in range(uptr[k], uptr[k + 1]):
                j = uidx[y]
                A[i, j] -= f * A[k, j]
    return worst


@njit(cache=True, inline="always")
def solve_lu(lptr, lidx, uptr, uidx, A, x):
    """x <- Phi_u^-1 x in place: x in pivot-row order in, pivot-column order (coordinates dep[p]) out."""
    m = A.shape[0]
    for k in range(m):
        xk = x[k]
        for t in range(lptr[k], lptr[k + 1]):
            i = lidx[t]
            x[i] -= A[i, k] * xk
    for k in range(m - 1, -1, -1):
        s = x[k]
        for t in range(uptr[k], uptr[k + 1]):
            j = uidx[t]
            s -= A[k, j] * x[j]
        x[k] = s * A[k, k]


@njit(cache=True, inline="always")
def solve_lu_columns(lptr, lidx, uptr, uidx, A, X):
    """X <- Phi_u^-1 X for all columns of X at once (as :func:`solve_lu`)."""
    m, r = X.shape
    for k in range(m):
        for t in range(lptr[k], lptr[k + 1]):
            i = lidx[t]
            f = A[i, k]
            for c in range(r):
                X[i, c] -= f * X[k, c]
    for k in range(m - 1, -1, -1):
        for t in range(uptr[k], uptr[k + 1]):
            j = uidx[t]
            f = A[k, j]
            for c in range(r):
                X[k, c] -= f * X[j, c]
        d = A[k, k]
        for c in range(r):
            X[k, c] *= d


@njit(cache=True, inline="always")
def reduced_system(dep, indep, mass, Ru, cu, g, Mr, fr, av, a):
    """(R^T M R) a_v = R^T (g - M c) by Cholesky (4 x 4), then a_u = R_u a_v + c_u, into a."""
    m, nv = dep.shape[0], indep.shape[0]
    for i in range(nv):
        fr[i] = g[indep[i]]
        for j in range(nv):
            Mr[i, j] = 0.0
        Mr[i, i] = mass[indep[i]]
    for p in range(m):
        c = dep[p]
        mc = mass[c]
        gc = g[c] - mc * cu[p]
        for i in range(nv):
            w = mc * Ru[p, i]
            fr[i] += Ru[p, i] * gc
            for j in range(i + 1):
                Mr[i, j] += w * Ru[p, j]
    for j in range(nv):  # Cholesky, lower triangle
        d = Mr[j, j]
        for k in range(j):
            d -= Mr[j, k] * Mr[j, k]
        d = math.sqrt(d)
        Mr[j, j] = d
        for i in range(j + 1, nv):
            s = Mr[i, j]
            for k in range(j):
                s -= Mr[i, k] * Mr[j, k]
            Mr[i, j] = s / d
    for i in range(nv):
        s = fr[i]
        for k in range(i):
            s -= Mr[i, k] * av[k]
        av[i] = s / Mr[i, i]
    for i in range(nv - 1, -1, -1):
        s = av[i]
        for k in range(i + 1, nv):
            s -= Mr[k, i] * av[k]
        av[i] = s / Mr[i, i]
    for j in range(nv):
        a[indep[j]] = av[j]
    for p in range(m):
        s = cu[p]
        for j in range(nv):
            s += Ru[p, j] * av[j]
        a[dep[p]] = s


@njit(cache=True)
def reduced_accel(t, qv, vv, speed, P, part, Z, W, inc, v0i, cout, tol, maxit):
    """Accelerations of all coordinates (Z.a) at the reduced state (q_v, v_v), the full q, v in Z.q,
    Z.v, contact outputs in cout. Returns OK, NO_CONVERGENCE or REPARTITION. (:func:`reduced_accel_inline`
    is the same, compiled into its caller.)"""
    return reduced_accel_inline(t, qv, vv, speed, P, part, Z, W, inc, v0i, cout, tol, maxit)


@njit(cache=True, inline="always")
def reduced_accel_inline(t, qv, vv, speed, P, part, Z, W, inc, v0i, cout, tol, maxit):
    """:func:`reduced_accel` compiled into its caller. Steps: q_u by Newton from the predicted last
    solution with the last factorisation (frozen), Phi_u factorised at the solution, [R_u | s_u] and v_u,
    gamma at the exact velocities (the constraints again) and c_u, the forces, the reduced system."""
    q, v, A, V, X, x, cu, cnt = Z.q, Z.v, Z.A, Z.V, Z.Ru, Z.x, Z.cu, Z.counts
    dep, indep, rowpos = part.dep, part.indep, part.rowpos
    lptr, lidx, uptr, uidx = part.lptr, part.lidx, part.uptr, part.uidx
    phi, Jv, nu, gam = W.phi, W.Jv, W.nu, W.gam
    m, nv = A.shape[0], qv.shape[0]
    cnt[0] += 1
    if Z.have[0]:  # predictor: q_u + R_u dq_v + s_u dt, v_u = R_u v_v + s_u (the last call's)
        dt = t - Z.tlast[0]
        qlast, qvlast = Z.qlast, Z.qvlast
        for p in range(m):
            c = dep[p]
            s = qlast[c] + X[p, nv] * dt
            sv = X[p, nv]
            for j in range(nv):
                s += X[p, j] * (qv[j] - qvlast[j])
                sv += X[p, j] * vv[j]
            q[c] = s
            v[c] = sv
    for j in range(nv):
        q[indep[j]] = qv[j]
        v[indep[j]] = vv[j]
    it = 0
    err_prev = math.inf
    while True:
        K.constraints(t, q, v, speed, P, W)
        cnt[2] += 1
        err = 0.0
        for k in range(m):
            err = max(err, abs(phi[k]))
        if err <= tol:
            break
        if it == maxit or not err < 0.1:
            cnt[3] += 1  # no solution near: q back to the last one and Phi_u factorised there for the next call
            for i in range(q.shape[0]):
                q[i] = Z.qlast[i]
            K.constraints(Z.tlast[0], q, v, speed, P, W)
            load_factor(part.zidx, part.amap, part.vmap, lptr, lidx, uptr, uidx, part.piv0, Jv, A, V)
            return NO_CONVERGENCE
        if it >= 2 or err > 0.5 * err_prev:  # the frozen factorisation converges too slowly: Phi_u at this q
            load_factor(part.zidx, part.amap, part.vmap, lptr, lidx, uptr, uidx, part.piv0, Jv, A, V)
            cnt[4] += 1
        err_prev = err
        for k in range(m):
            x[rowpos[k]] = phi[k]
        solve_lu(lptr, lidx, uptr, uidx, A, x)
        for p in range(m):
            q[dep[p]] -= x[p]
        it += 1
        cnt[1] += 1
    worst = load_factor(part.zidx, part.amap, part.vmap, lptr, lidx, uptr, uidx, part.piv0, Jv, A, V)
    if worst < part.min_pivot:
        return REPARTITION
    for p in range(m):  # [R_u | s_u] = Phi_u^-1 [-Phi_v | nu], v_u
        for j in range(nv):
            X[p, j] = -V[p, j]
    for k in range(m):
        X[rowpos[k], nv] = nu[k]
    solve_lu_columns(lptr, lidx, uptr, uidx, A, X)
    for p in range(m):
        s = X[p, nv]
        for j in range(nv):
            s += X[p, j] * vv[j]
        v[dep[p]] = s
    K.constraints(t, q, v, speed, P, W)  # gamma at the exact velocities
    cnt[2] += 1
    for k in range(m):
        cu[rowpos[k]] = gam[k]
    solve_lu(lptr, lidx, uptr, uidx, A, cu)
    K.element_forces(q, v, P, W.g)
    K.clearance_arrays(q, v, P, W, inc, v0i, cout, True)
    reduced_system(dep, indep, part.mass, X, cu, W.g, Z.Mr, Z.fr, Z.av, Z.a)
    Z.tlast[0] = t
    for i in range(q.shape[0]):
        Z.qlast[i] = q[i]
    for j in range(nv):
        Z.qvlast[j] = qv[j]
    Z.have[0] = 1
    return OK


# --- the check and the timings on a run's states ----------------------------------------------------------------

@njit(cache=True)
def check_states(ts, qs, vs, speed, P, part, Z, W, inc, v0i, cout, tol, maxit, a_part, a_aug, q_part, lam, W2):
    """The reduced accelerations at each state in order (reduced coordinates taken from it) and
    kernel.accel at the reduced method's own full state. Returns the number of states done."""
    nv = part.indep.shape[0]
    qv, vv = np.empty(nv), np.empty(nv)
    for i in range(ts.shape[0]):
        for j in range(nv):
            qv[j] = qs[i, part.indep[j]]
            vv[j] = vs[i, part.indep[j]]
        if reduced_accel(ts[i], qv, vv, speed, P, part, Z, W, inc[i], v0i[i], cout, tol, maxit) != OK:
            return i
        a_part[i] = Z.a
        q_part[i] = Z.q
        K.accel_arrays(ts[i], Z.q.copy(), Z.v.copy(), speed, P, W2, (0.0, 0.0), inc[i], v0i[i], a_aug[i], lam, cout)
    return ts.shape[0]


def _timers():
    @njit
    def aug(reps, ts, qs, vs, speed, P, W, inc, v0i, a, lam, cout):
        for _ in range(reps):
            for i in range(ts.shape[0]):
                K.accel_arrays(ts[i], qs[i], vs[i], speed, P, W, (0.0, 0.0), inc[i], v0i[i], a, lam, cout)

    @njit
    def part_whole(reps, ts, qvs, vvs, speed, P, part, Z, W, inc, v0i, cout, tol, maxit):
        for _ in range(reps):
            for i in range(ts.shape[0]):
                reduced_accel(ts[i], qvs[i], vvs[i], speed, P, part, Z, W, inc[i], v0i[i], cout, tol, maxit)

    @njit
    def constraints(reps, ts, qs, vs, speed, P, W):
        for _ in range(reps):
            for i in range(ts.shape[0]):
                K.constraints(ts[i], qs[i], vs[i], speed, P, W)

    @njit
    def forces(reps, ts, qs, vs, speed, P, W, inc, v0i, cout, css, sns):
        for _ in range(reps):
            for i in range(ts.shape[0]):
                for b in range(css.shape[1]):
                    W.cs[b] = css[i, b]
                    W.sn[b] = sns[i, b]
                K.element_forces(qs[i], vs[i], P, W.g)
                K.clearance_arrays(qs[i], vs[i], P, W, inc[i], v0i[i], cout, True)

    @njit
    def factor(reps, Jvs, P, part, A, V):
        zidx, amap, vmap, lptr, lidx, uptr, uidx, piv0 = (part.zidx, part.amap, part.vmap, part.lptr, part.lidx,
                                                          part.uptr, part.uidx, part.piv0)
        for _ in range(reps):
            for i in range(Jvs.shape[0]):
                load_factor(zidx, amap, vmap, lptr, lidx, uptr, uidx, piv0, Jvs[i], A, V)

    @njit
    def substitution(reps, As, part, x, b):
        for _ in range(reps):
            for i in range(As.shape[0]):
                for p in range(b.shape[0]):
                    x[p] = b[p]
                solve_lu(part.lptr, part.lidx, part.uptr, part.uidx, As[i], x)

    @njit
    def copy_only(reps, As, part, x, b):
        for _ in range(reps):
            for i in range(As.shape[0]):
                for p in range(b.shape[0]):
                    x[p] = b[p]
                x[0] += As[i, 0, 0]

    @njit
    def columns(reps, As, part, X, B):
        for _ in range(reps):
            for i in range(As.shape[0]):
                X[:] = B
                solve_lu_columns(part.lptr, part.lidx, part.uptr, part.uidx, As[i], X)

    @njit
    def columns_copy(reps, As, part, X, B):
        for _ in range(reps):
            for i in range(As.shape[0]):
                X[:] = B
                X[0, 0] += As[i, 0, 0]

    @njit
    def reduced(reps, Rus, cus, gs, part, Z):
        dep, indep, mass, Ru, cu, Mr, fr, av, a = part.dep, part.indep, part.mass, Z.Ru, Z.cu, Z.Mr, Z.fr, Z.av, Z.a
        for _ in range(reps):
            for i in range(Rus.shape[0]):
                Ru[:] = Rus[i]
                cu[:] = cus[i]
                reduced_system(dep, indep, mass, Ru, cu, gs[i], Mr, fr, av, a)

    @njit
    def reduced_copy(reps, Rus, cus, gs, part, Z):
        for _ in range(reps):
            for i in range(Rus.shape[0]):
                Z.Ru[:] = Rus[i]
                Z.cu[:] = cus[i]

    @njit
    def schur_solve(reps, Jvs, P, S, rhs, lam):
        for _ in range(reps):
            for i in range(Jvs.shape[0]):
                K.schur(P, Jvs[i], S)
                K.cholesky_solve(S, rhs, lam, P.s_first)

    return {"aug": aug, "part": part_whole, "constraints": constraints, "forces": forces, "factor": factor,
            "substitution": substitution, "copy_only": copy_only, "columns": columns, "columns_copy": columns_copy,
            "reduced": reduced, "reduced_copy": reduced_copy, "schur_solve": schur_solve}


def sample_states(scene, speed, revolutions: float = 1.0):
    """The 20 kHz samples of one default revolution (y from the continuous extension), each projected
    onto the position and velocity constraints (tol 1e-13), with contact modes as the table shows them."""
    from wearbench.model import simulate

    with watched_loop(whole_state=True) as kept:
        res = simulate(scene, revolutions=revolutions)
    n, P, W = scene.n, scene.params, scene.work()
    ts = np.ascontiguousarray(kept["t"])
    qs = np.ascontiguousarray(kept["y"][:, :n])
    vs = np.ascontiguousarray(kept["y"][:, n:])
    for i in range(ts.size):
        K.project(ts[i], qs[i], vs[i], speed, P, W, 1e-13, 20)
    return res, ts, qs, vs, *contact_modes(scene, res)


def check_and_time(label: str, scene, repeat: int) -> dict:
    P, speed, n, m = scene.params, scene.bench.speed, scene.n, scene.m
    nc = len(scene.clearance_joints)
    _, ts, qs, vs, inc, v0i = sample_states(scene, speed)
    part = choose_partition(scene, 0.0, qs[0], vs[0], speed)
    names = [f"{scene.bodies[c // 3]}.{'xy'[c % 3] if c % 3 < 2 else 'theta'}" for c in part.indep]
    Z = new_reduced(scene, part, ts[0], qs[0], vs[0], speed)
    W, W2 = scene.work(), scene.work()
    cout = np.zeros((nc, K.NCO))
    a_part, a_aug, q_part = np.zeros((ts.size, n)), np.zeros((ts.size, n)), np.zeros((ts.size, n))
    done = check_states(ts, qs, vs, speed, P, part, Z, W, inc, v0i, cout, NEWTON_TOL, NEWTON_MAXIT, a_part, a_aug,
                        q_part, np.zeros(m), W2)
    reparts, segments = 0, []
    start = 0
    while done < ts.size - start:  # re-partition where the dependent block degenerates, go on from there
        if reparts and done == 0:
            raise RuntimeError(f"{label}: the reduced right-hand side fails at t = {ts[start]} after a re-partition")
        reparts += 1
        segments.append(start + done)
        start += done
        part = choose_partition(scene, ts[start], qs[start], vs[start], speed)
        Z = new_reduced(scene, part, ts[start], qs[start], vs[start], speed)
        sl = slice(start, None)
        done = check_states(ts[sl], qs[sl], vs[sl], speed, P, part, Z, W, inc[sl], v0i[sl], cout, NEWTON_TOL,
                            NEWTON_MAXIT, a_part[sl], a_aug[sl], q_part[sl], np.zeros(m), W2)
    rel = np.abs(a_part - a_aug).max(axis=1) / np.abs(a_aug).max(axis=1)
    gap = np.abs(q_part - qs).max()
    calls, updates, cevals = int(Z.counts[0]), int(Z.counts[1]), int(Z.counts[2])
    print(f"\n{label} ({scene.description}): {ts.size} states of one default revolution (20 kHz samples, projected)")
    nnz = int(_pattern(scene, 0.0, qs[0], vs[0], speed)[:, part.dep].sum())
    print(f"  independent coordinates at t = 0: {', '.join(names)}; Phi_u has {nnz} non-zeros, its LU "
          f"{part.zidx.size} fill-in; re-partitions over the revolution's samples: {reparts} "
          f"(at samples {segments[:6]})")
    print(f"  check: 24 accelerations, partitioned against kernel.accel at the same state: largest relative "
          f"error (|a_p - a_aug|_inf / |a_aug|_inf) {rel.max():.2e}, median {np.median(rel):.1e}; "
          f"partitioned q against the projected samples {gap:.1e}")
    print(f"  Newton (last segment, samples 50 us apart): {updates / calls:.2f} updates and "
          f"{cevals / calls:.2f} constraint evaluations per call")
    # timings on the last segment's states, in order (the Newton starts as in the check)
    sl = slice(start, None)
    tt, qq, vv_, ii, vi = ts[sl], qs[sl], vs[sl], inc[sl], v0i[sl]
    qvs = np.ascontiguousarray(qq[:, part.indep])
    vvs = np.ascontiguousarray(vv_[:, part.indep])
    T = _timers()
    Jvs, As, Rus, cus, gs = [], [], [], [], []
    css, sns = np.zeros((tt.size, n // 3)), np.zeros((tt.size, n // 3))
    Zr = new_reduced(scene, part, tt[0], qq[0], vv_[0], speed)
    for i in range(tt.size):
        reduced_accel(tt[i], qvs[i], vvs[i], speed, P, part, Zr, W, ii[i], vi[i], cout, NEWTON_TOL, NEWTON_MAXIT)
        K.constraints(tt[i], Zr.q.copy(), Zr.v.copy(), speed, P, W)
        Jvs.append(W.Jv.copy())
        css[i], sns[i] = W.cs, W.sn
        As.append(Zr.A.copy())
        Rus.append(Zr.Ru.copy())
        cus.append(Zr.cu.copy())
        K.element_forces(Zr.q, Zr.v, P, W.g)
        K.clearance_arrays(Zr.q, Zr.v, P, W, ii[i], vi[i], cout, True)
        gs.append(W.g.copy())
    # the parts on every k-th state (<= 400: their recorded arrays stay in cache, as a right-hand side's do)
    every = max(1, tt.size // 400)
    Jvs, As, Rus, cus, gs = (np.ascontiguousarray(np.array(x)[::every]) for x in (Jvs, As, Rus, cus, gs))
    ts_p, qs_p, vs_p, inc_p, v0i_p = (np.ascontiguousarray(x[::every]) for x in (tt, qq, vv_, ii, vi))
    css, sns = np.ascontiguousarray(css[::every]), np.ascontiguousarray(sns[::every])
    upd = Zr.counts[1] / Zr.counts[0]
    best: dict[str, float] = {}
    Zt = new_reduced(scene, part, tt[0], qq[0], vv_[0], speed)
    for _ in range(repeat):
        for key, fn, args, per in (
                ("aug", T["aug"], (tt, qq, vv_, speed, P, W, ii, vi, np.zeros(n), np.zeros(m), cout), tt.size),
                ("part", T["part"], (tt, qvs, vvs, speed, P, part, Zt, W, ii, vi, cout, NEWTON_TOL, NEWTON_MAXIT),
                 tt.size),
                ("constraints", T["constraints"], (ts_p, qs_p, vs_p, speed, P, W), ts_p.size),
                ("forces", T["forces"], (ts_p, qs_p, vs_p, speed, P, W, inc_p, v0i_p, cout, css, sns), ts_p.size),
                ("factor", T["factor"], (Jvs, P, part, np.zeros((m, m)), np.zeros((m, part.indep.size))), ts_p.size),
                ("substitution", T["substitution"], (As[:1].repeat(ts_p.size, 0), part, np.zeros(m), np.ones(m)),
                 ts_p.size),
                ("copy_only", T["copy_only"], (As[:1].repeat(ts_p.size, 0), part, np.zeros(m), np.ones(m)), ts_p.size),
                ("columns", T["columns"], (As[:1].repeat(ts_p.size, 0), part, np.zeros((m, 5)), np.ones((m, 5))),
                 ts_p.size),
                ("columns_copy", T["columns_copy"], (As[:1].repeat(ts_p.size, 0), part, np.zeros((m, 5)),
                                                     np.ones((m, 5))), ts_p.size),
                ("reduced", T["reduced"], (Rus, cus, gs, part, Zr), ts_p.size),
                ("reduced_copy", T["reduced_copy"], (Rus, cus, gs, part, Zr), ts_p.size),
                ("schur_solve", T["schur_solve"], (Jvs, P, np.zeros((m, m)), np.ones(m), np.zeros(m)), ts_p.size)):
            sec = clock(fn, *args, budget=0.2, best_of=1) / per  # --repeat interleaves the best-of
            best[key] = min(best.get(key, math.inf), sec)
    sub = max(0.0, best["substitution"] - best["copy_only"])
    cols = max(0.0, best["columns"] - best["columns_copy"])
    red = max(0.0, best["reduced"] - best["reduced_copy"])
    cev = Zr.counts[2] / Zr.counts[0]
    parts = {
        f"position solve: {cev - 1:.2f} constraint evaluations + {upd:.2f} substitutions": (cev - 1) * best["constraints"]
        + upd * sub,
        "velocity: LU of Phi_u (fixed order) + [R_u | s_u] (5 columns)": best["factor"] + cols,
        "gamma at the exact velocities (constraints again) + 1 substitution": best["constraints"] + sub,
        "contact and force elements": best["forces"],
        "reduced mass matrix R^T M R, R^T (g - M c), 4 x 4 solve, a_u": red,
    }
    parts["rest (predictor, copies)"] = max(0.0, best["part"] - sum(parts.values()))
    print(f"  one evaluation, CPU us (compiled loops; whole evaluations over {tt.size} states in order, parts over "
          f"{ts_p.size} of them; interleaved, best of {repeat}):")
    print(f"    {'augmented (kernel.accel)':<74} {best['aug'] * 1e6:7.3f}")
    print(f"      {'of it: constraints / contact and forces / Schur + Cholesky (m = 20)':<72} "
          f"{best['constraints'] * 1e6:.3f} / {best['forces'] * 1e6:.3f} / {best['schur_solve'] * 1e6:.3f}")
    print(f"    {'partitioned (reduced_accel)':<74} {best['part'] * 1e6:7.3f}   ratio aug / part "
          f"{best['aug'] / best['part']:.2f}x")
    for what, sec in parts.items():
        print(f"      {what:<72} {sec * 1e6:7.3f}")
    return {"label": label, "part": part, "reparts": reparts, "rel": float(rel.max()), "aug": best["aug"],
            "partitioned": best["part"]}


# --- one revolution with DOPRI5 on the reduced state ------------------------------------------------------------

@njit(cache=True, inline="always")
def _rhs(t, y, speed, P, part, Z, W, inc, v0i, cout, f):
    nv = y.shape[0] // 2
    st = reduced_accel_inline(t, y[:nv], y[nv:], speed, P, part, Z, W, inc, v0i, cout, NEWTON_TOL, NEWTON_MAXIT)
    for j in range(nv):
        f[j] = y[nv + j]
        f[nv + j] = Z.a[part.indep[j]]
    return st


@njit(cache=True)
def _restore(Z, t, y, qacc, Xacc, Aacc):
    """The last solution back to the accepted state (t, y) (its full q, [R_u | s_u] and factorisation)."""
    Z.tlast[0] = t
    for i in range(qacc.shape[0]):
        Z.qlast[i] = qacc[i]
    for j in range(Z.qvlast.shape[0]):
        Z.qvlast[j] = y[j]
    Z.Ru[:] = Xacc
    Z.A[:] = Aacc


@njit(cache=True)
def reduced_loop(scheme, t, y, h, t_end, err_old, k, atol, rtol, hmax, speed, P, part, Z, W, inc, v0i, cout_old,
                 stats, ts_out, acc_out, sensor, Z2, W2, qacc, vacc):
    """DOPRI5 on the reduced state y = (q_v, v_v) with the default's step control (error norm over
    y's components with atol, rtol; rejection shrink; PI control; contact modes after each accepted
    step; a stage where the position solve fails rejects the step with h / 4); output samples at ts_out
    (the slider acceleration, a right-hand side on the continuous extension with its own work arrays Z2,
    W2). stats: steps, rejected, t, h, err_old, out index, steps rejected for a failed position solve.
    Returns OK, or the right-hand side's status (the state at the last accepted step in qacc, vacc)."""
    N = y.shape[0]
    nv = N // 2
    ynew, ytmp, yo, fo = np.empty(N), np.empty(N), np.empty(N), np.empty(N)
    dbs = np.empty(scheme.d.shape[0])
    cnew = np.empty_like(cout_old)
    c2 = np.empty_like(cout_old)
    A_, C_, E = scheme.a, scheme.c, scheme.e
    end = scheme.end
    factor_max = 5.0
    iout = int(stats[5])
    # the accepted state's solution, velocity transformation and factorisation: a rejected step's next
    # attempt starts its Newton from them, not from the rejected attempt's last stage
    Xacc, Aacc = Z.Ru.copy(), Z.A.copy()
    for i in range(Z.q.shape[0]):
        qacc[i] = Z.q[i]
        vacc[i] = Z.v[i]
    while t < t_end:
        hh = min(h, t_end - t)
        last = hh >= t_end - t
        st = OK
        for s in range(1, end + 1):
            for i in range(N):
                acc = 0.0
                for r in range(s):
                    acc += A_[s, r] * k[r, i]
                ytmp[i] = y[i] + hh * acc
            st = _rhs(t + C_[s] * hh, ytmp, speed, P, part, Z, W, inc, v0i, cnew, k[s])
            if st != OK:
                break
        if st == NO_CONVERGENCE and hh > 1e-9:  # a stage the mechanism cannot assemble at: a rejected step
            stats[1] += 1
            stats[6] += 1
            h = hh * 0.25
            factor_max = 1.0
            _restore(Z, t, y, qacc, Xacc, Aacc)
            continue
        if st != OK:
            stats[2], stats[3], stats[4], stats[5] = t, h, err_old, iout
            return st
        for i in range(N):
            ynew[i] = ytmp[i]
        err = 0.0
        for i in range(N):
            e = 0.0
            for r in range(E.shape[0]):
                e += E[r] * k[r, i]
            sc = atol[i] + rtol * max(abs(y[i]), abs(ynew[i]))
            err += (hh * e / sc) ** 2
        err = math.sqrt(err / N)
        if not math.isfinite(err):
            err = 1e10
        if err > 1.0:
            stats[1] += 1
            h = hh * max(0.2, 0.9 * err ** -scheme.expo)
            factor_max = 1.0
            _restore(Z, t, y, qacc, Xacc, Aacc)
            continue
        t_new = t_end if last else t + hh
        for i in range(Z.q.shape[0]):
            qacc[i] = Z.q[i]
            vacc[i] = Z.v[i]
        Xacc[:] = Z.Ru
        Aacc[:] = Z.A
        while iout < ts_out.shape[0] and ts_out[iout] <= t_new:
            I.extension(scheme.d, y, hh, k, (ts_out[iout] - t) / hh, yo, fo, dbs)
            reduced_accel(ts_out[iout], yo[:nv], yo[nv:], speed, P, part, Z2, W2, inc, v0i, c2, NEWTON_TOL,
                          NEWTON_MAXIT)
            b = int(sensor[0])
            _, _, acc = K.point_along(Z2.q[3 * b], Z2.q[3 * b + 1], Z2.q[3 * b + 2], Z2.v[3 * b], Z2.v[3 * b + 1],
                                      Z2.v[3 * b + 2], Z2.a[3 * b], Z2.a[3 * b + 1], Z2.a[3 * b + 2], sensor[1],
                                      sensor[2], sensor[3])
            acc_out[iout] = acc
            iout += 1
        if I.update_modes(cout_old, cnew, inc, v0i):
            st = _rhs(t_new, ynew, speed, P, part, Z, W, inc, v0i, cnew, k[end])
            if st != OK:
                stats[2], stats[3], stats[4], stats[5] = t, h, err_old, iout
                return st
        for i in range(N):
            y[i] = ynew[i]
            k[0, i] = k[end, i]
        for c in range(cnew.shape[0]):
            for j in range(cnew.shape[1]):
                cout_old[c, j] = cnew[c, j]
        t = t_new
        stats[0] += 1
        h, err_old = I.next_step(hh, err, err_old, factor_max, hmax, scheme.expo_pi)
        factor_max = 5.0
    stats[2], stats[3], stats[4], stats[5] = t, h, err_old, iout
    return OK


def run_reduced(scene, t_end: float, ts_out: np.ndarray) -> dict:
    """One run of the reduced DOPRI5 from the default's start (projected assembly, journals centred):
    counts, CPU and the slider acceleration at ts_out. Re-partitions in Python when asked."""
    from wearbench.model.methods import Dopri5
    from wearbench.model.simulation import error_scales, step_cap

    P, speed, n = scene.params, scene.bench.speed, scene.n
    nc = len(scene.clearance_joints)
    scheme = Dopri5.tableau.scheme()
    atol_full = error_scales(scene, Dopri5.atol)
    hmax = step_cap(scene, speed, False)
    q, v = scene.q0.copy(), scene.v_unit * speed
    W = scene.work()
    K.project(0.0, q, v, speed, P, W, max(2e-15, min(1e-11, 1e-2 * Dopri5.atol)), 20)
    sensor = np.array([scene.sensor[0], *scene.sensor[1], scene.sensor[2]], dtype=float)
    inc, v0i = np.zeros(nc, np.int64), np.zeros(nc)
    cout = np.zeros((nc, K.NCO))
    stats = np.zeros(7)
    acc_out = np.zeros(ts_out.size)
    t, h, err_old = 0.0, 1e-6, 1e-4
    qacc, vacc = q.copy(), v.copy()
    calls = updates = cevals = reparts = fresh = shrunk = 0
    cpu = 0.0
    first = True
    while True:
        t0 = time.process_time()
        part = choose_partition(scene, t, qacc, vacc, speed)
        Z = new_reduced(scene, part, t, qacc, vacc, speed)
        Z2 = new_reduced(scene, part, t, qacc, vacc, speed)
        W2 = scene.work()
        y = np.concatenate([qacc[part.indep], vacc[part.indep]])
        atol = np.concatenate([atol_full[part.indep], atol_full[n + part.indep]])
        k = np.zeros((scheme.end + 1, y.size))
        if _rhs(t, y, speed, P, part, Z, W, inc, v0i, cout, k[0]) != OK:
            raise RuntimeError(f"reduced right-hand side failed at t = {t}")
        if first:
            for c in range(nc):
                if cout[c, K.CO_PEN] > 0:
                    inc[c], v0i[c] = 1, impact_speed(cout[c, K.CO_VN])
            first = False
        st = reduced_loop(scheme, t, y, h, t_end, err_old, k, atol, Dopri5.rtol, hmax, speed, P, part, Z, W, inc,
                          v0i, cout, stats, ts_out, acc_out, sensor, Z2, W2, qacc, vacc)
        cpu += time.process_time() - t0
        calls += int(Z.counts[0])
        updates += int(Z.counts[1])
        cevals += int(Z.counts[2])
        fresh += int(Z.counts[4])
        t, h, err_old = stats[2], stats[3], stats[4]
        if st == OK:
            break
        if st != REPARTITION:
            raise RuntimeError(f"reduced run failed with status {st} at t = {t}")
        same = choose_partition(scene, t, qacc, vacc, speed)
        if np.array_equal(same.dep, part.dep) and np.array_equal(same.rowpos, part.rowpos):
            h *= 0.25  # the same partition at the step's start: the stage went too far, not the partition
            shrunk += 1
            if h < 1e-12:
                raise RuntimeError(f"reduced run: the dependent block degenerates within 1e-12 s of t = {t}")
        reparts += 1
    return {"steps": int(stats[0]), "rejected": int(stats[1]), "nfev": calls, "updates": updates, "cevals": cevals,
            "reparts": reparts, "cpu": cpu, "acc": acc_out, "fresh": fresh, "newton_rejects": int(stats[6]), "shrunk": shrunk}


def compare_revolution(label: str, scene, repeat: int, revolutions: float) -> None:
    from wearbench.model import simulate

    speed = scene.bench.speed
    t_rev = revolutions * 2 * math.pi / abs(speed)
    simulate(scene, t_end=1e-3)  # compiled
    run_reduced(scene, 1e-3, np.zeros(0))  # compiled too: --repeat 1 would time its compilation
    best_def, best_red = None, None
    for _ in range(repeat):
        with watched_loop() as loop:
            t0 = time.process_time()
            res = simulate(scene, revolutions=revolutions)
            cpu = time.process_time() - t0
        if best_def is None or cpu < best_def[0]:
            best_def = (cpu, loop["cpu"], res)
        red = run_reduced(scene, t_rev, np.zeros(0))
        if best_red is None or red["cpu"] < best_red["cpu"]:
            best_red = red
    cpu, loop, res = best_def
    s = res.summary
    tab = res.table
    horizon = tab["t"].to_numpy() <= 0.040
    ts_cmp = tab["t"].to_numpy()[horizon]
    red_s = run_reduced(scene, t_rev, ts_cmp)  # the same trajectory, with samples
    acc_def = tab["slider_acc"].to_numpy()[horizon]
    # the yardstick: a tight reference (the motion is chaotic: the default itself parts from it after ~20 ms)
    acc_ref = simulate(scene, t_end=0.040, rtol=1e-10, atol=1e-13).table["slider_acc"].to_numpy()[:ts_cmp.size]

    def dev(x, ref, until):
        w = ts_cmp <= until
        return float(np.sqrt(np.mean((x[w] - ref[w]) ** 2) / np.mean(ref[w] ** 2)))

    r = best_red
    print(f"\n{label}: {revolutions:g} revolutions with DOPRI5, rtol 1e-6 / atol 1e-9 m, from the same start (best of "
          f"{repeat}, interleaved, CPU; per revolution)")
    print(f"  {'':<34} {'accepted':>8} {'rejected':>8} {'evaluations':>11} {'CPU ms':>8} {'us/eval':>8}")
    rv = revolutions
    print(f"  {'default simulate (48 components)':<34} {s['steps'] / rv:8.0f} {s['rejected_steps'] / rv:8.0f} "
          f"{s['function_evaluations'] / rv:11.0f} {cpu * 1e3 / rv:8.1f} {'':>8}   (compiled loop {loop * 1e3 / rv:.1f} ms, "
          f"table and peaks included)")
    print(f"  {'partitioned (8 components)':<34} {r['steps'] / rv:8.0f} {r['rejected'] / rv:8.0f} {r['nfev'] / rv:11.0f} "
          f"{r['cpu'] * 1e3 / rv:8.1f} {r['cpu'] / r['nfev'] * 1e6:8.2f}   (no table; {r['reparts']} re-partitions in all; "
          f"Newton {r['updates'] / r['nfev']:.2f} updates ({r['fresh'] / r['nfev']:.3f} refactorised), "
          f"{r['cevals'] / r['nfev']:.2f} constraint evaluations per evaluation; {r['newton_rejects']} steps rejected "
          f"for a failed position solve in all)")
    print(f"  CPU default / partitioned: {cpu / r['cpu']:.2f}x (whole simulate), {loop / r['cpu']:.2f}x "
          f"(compiled loop only); evaluations {s['function_evaluations'] / r['nfev']:.2f}x, attempted steps "
          f"{(s['steps'] + s['rejected_steps']) / (r['steps'] + r['rejected']):.2f}x")
    same = (red_s["steps"], red_s["rejected"]) == (r["steps"], r["rejected"])
    print("  slider acceleration, RMS error relative to the reference's RMS (reference: rtol 1e-10, atol 1e-13 m), "
          "0-20 / 0-40 ms:")
    for what, x, ref in (("default against the reference", acc_def, acc_ref),
                         ("partitioned against the reference", red_s["acc"], acc_ref),
                         ("partitioned against the default", red_s["acc"], acc_def)):
        print(f"    {what:<40} {dev(x, ref, 0.020):7.2%} / {dev(x, ref, 0.040):7.2%}")
    print(f"  (the sampled run takes the same steps as the timed one: {same})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="interleaved timings (best of)")
    ap.add_argument("--states", nargs="+", default=list(STATES), choices=list(STATES))
    ap.add_argument("--no-revolution", action="store_true", help="skip the DOPRI5 revolution")
    ap.add_argument("--no-check", action="store_true", help="skip the check and the per-evaluation timings")
    ap.add_argument("--revolutions", type=float, default=3.0, help="revolutions of the DOPRI5 comparison")
    args = ap.parse_args()
    from wearbench.bench.load import load_bench, shipped_bench
    from wearbench.model.realisation import state_scene

    bench = load_bench(shipped_bench("ninebar-testbed"))
    by_name = {s.name: s for s in bench.states}
    print("test bed ninebar-testbed, nominal bench; CPU time (time.process_time) on the shared machine")
    for key in args.states:
        scene = state_scene(bench, by_name[STATES[key]])
        if not args.no_check:
            check_and_time(STATES[key], scene, args.repeat)
        if not args.no_revolution:
            compare_revolution(STATES[key], scene, args.repeat, args.revolutions)


if __name__ == "__main__":
    main()
