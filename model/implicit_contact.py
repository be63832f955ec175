"""The step of method "imex": linearly implicit Euler extrapolation with the clearance contacts implicit.

A W-method (linearly implicit, any Jacobian approximation keeps its order; Hairer, Wanner, Solving
ODE II, sec. IV.7 and IV.9 (SEULEX); Deuflhard's LIMEX): each of ``kc`` columns takes n_j = j + 1
linearly implicit Euler substeps of H / n_j,

    (I - h J) (y_{i+1} - y_i) = h f(t_i, y_i),

and the Aitken-Neville table extrapolates them to order kc; the difference of its last two entries
in the last row is the embedded error estimate (order kc - 1). J keeps only the stiff part of f = (v, a):
dq/dt = v, and each clearance joint's contact force as a function of the relative journal position
e and velocity de/dt (the normal force law's derivatives along the contact normal, and the normal's
turn with e), mapped to accelerations through the constrained system:

    J = [[0, I], [U Kp G, U Kv G]],   G = de/dq,   U = (M^-1 - M^-1 Phi_q^T S^-1 Phi_q M^-1) G^T,

Kp, Kv (2 x 2 per joint) the force's derivatives. U costs two substitutions with the Cholesky factor
of S per joint (left by the right-hand side at the step's start); a substep's solve reduces
(Sherman-Morrison-Woodbury) to one system of two unknowns per joint with the Delassus matrix D = G U.
A step that ends in a contact no evaluation of it saw (an onset late in the step, which the
error estimate cannot see) is rejected. Without contact J is
[[0, I], [0, 0]] and a substep is the semi-implicit (symplectic) Euler step. Dense output: cubic Hermite
on the step's ends (its derivative gives the accelerations; multipliers linear). Imports numpy, numba
and the model's kernel only.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit
from wearbench.model import kernel as K
from wearbench.model.contact import FLORES, LANKARANI_NIKRAVESH, impact_speed

__all__ = ["ONSET_ERROR", "Work", "contact_jacobian", "liex_try", "work"]

ONSET_ERROR = 10.0  # the error norm that rejects a step with an unseen contact onset (its retry is about half as long)
# work arrays of :func:`liex_try`: time of the Jacobian (tj[0]), G (nc, 2, 2 sides, 3), U (n, 2 nc), D (2 nc,
# 2 nc), per-joint contact data jd (nc, 7: pen, vn, fn, |e|, psi, v0, the
# largest penetration the step's evaluations saw), Kp and Kv (nc, 2, 2), the small
# system and its right-hand side, a substep's state, f and multipliers, contact outputs, the
# extrapolation table tab (kc, kc, N), an n-vector x and the (m,) rhs/solution
Work = namedtuple("Work", "tj G U D jd Kp Kv Ms rz z w gq yi f lam cj tab x rhs sol")


@njit(cache=True)
def work(N, m, nc, kc):
    """Fresh work arrays for :func:`liex_try` (N = 2 n states, m constraints, nc joints, kc columns)."""
    n = N // 2
    return Work(np.full(1, np.nan), np.zeros((nc, 2, 2, 3)), np.zeros((n, 2 * nc)), np.zeros((2 * nc, 2 * nc)),
                np.zeros((nc, 7)), np.zeros((nc, 2, 2)), np.zeros((nc, 2, 2)), np.zeros((2 * nc, 2 * nc)),
                np.zeros(2 * nc), np.zeros(2 * nc), np.zeros(2 * nc), np.zeros(2 * nc), np.zeros(N), np.zeros(N),
                np.zeros(m), np.zeros((nc, K.NCO)), np.zeros((max(kc, 1), max(kc, 1), N)), np.zeros(n),
                np.zeros(m), np.zeros(m))


@njit(cache=True)
def contact_jacobian(q, P, inc, v0i, cout, W, X, implicit=True):
    """G, U, D and the joints' contact data of X at q, from the right-hand side just evaluated there (W holds
    its constraints, the bodies' cos/sin and the Cholesky factor of S; cout its contact outputs); not
    ``implicit``: the contact data alone (U and D stay as they are: zero)."""
    n = q.shape[0]
    minv, clr_b, clr_p = P.minv, P.clr_b, P.clr_p
    nc = clr_b.shape[0]
    G, U, D, jd, x = X.G, X.U, X.D, X.jd, X.x
    m = W.phi.shape[0]
    for c in range(nc):
        bi, bj = clr_b[c, 0], clr_b[c, 1]
        p = clr_p[c]
        for side in range(2):
            b = bi if side == 0 else bj
            sgn = -1.0 if side == 0 else 1.0
            if b < 0:
                for a in range(2):
                    for d in range(3):
                        G[c, a, side, d] = 0.0
                continue
            sx = p[K.CLR_SIX] if side == 0 else p[K.CLR_SJX]
            sy = p[K.CLR_SIY] if side == 0 else p[K.CLR_SJY]
            ax = W.cs[b] * sx - W.sn[b] * sy  # A_b s
            ay = W.sn[b] * sx + W.cs[b] * sy
            G[c, 0, side, 0] = sgn
            G[c, 0, side, 1] = 0.0
            G[c, 0, side, 2] = -sgn * ay
            G[c, 1, side, 0] = 0.0
            G[c, 1, side, 1] = sgn
            G[c, 1, side, 2] = sgn * ax
        co = cout[c]
        thi = 0.0 if bi < 0 else q[3 * bi + 2]
        jd[c, 0] = co[K.CO_PEN]
        jd[c, 1] = co[K.CO_VN]
        jd[c, 2] = co[K.CO_FN]
        jd[c, 3] = math.sqrt(co[K.CO_EX] ** 2 + co[K.CO_EY] ** 2)
        jd[c, 4] = co[K.CO_PHIB] + thi
        jd[c, 5] = v0i[c] if inc[c] != 0 else impact_speed(co[K.CO_VN])
    if not implicit:
        return
    # U = A_m G^T, column by column: M^-1 G^T minus its constraint part (substitutions with S's factor)
    for c in range(nc):
        for a in range(2):
            col = 2 * c + a
            for i in range(n):
                x[i] = 0.0
            for side in range(2):
                b = clr_b[c, side]
                if b >= 0:
                    for d in range(3):
                        x[3 * b + d] = minv[3 * b + d] * G[c, a, side, d]
            if m > 0:
                for r in range(m):
                    X.rhs[r] = K._j_times(P, W.Jv, x, r)
                K.substitute(W.S, X.rhs, X.sol, P.s_first)
                K._jt_times(P, W.Jv, X.sol, W.tmp)
                for i in range(n):
                    U[i, col] = x[i] - minv[i] * W.tmp[i]
            else:
                for i in range(n):
                    U[i, col] = x[i]
    for c in range(nc):
        for a in range(2):
            for col in range(2 * nc):
                D[2 * c + a, col] = _g_dot(G, clr_b, c, a, U[:, col])


@njit(cache=True, inline="always")
def _g_dot(G, clr_b, c, a, vec):
    """Row a of joint c's G times an n-vector."""
    s = 0.0
    for side in range(2):
        b = clr_b[c, side]
        if b >= 0:
            s += G[c, a, side, 0] * vec[3 * b] + G[c, a, side, 1] * vec[3 * b + 1] + G[c, a, side, 2] * vec[3 * b + 2]
    return s


@njit(cache=True)
def _stiffness(P, X):
    """Kp, Kv (per joint, 2 x 2: d(force on the journal)/de and /d(de/dt)): the force law's derivatives at
    the penetration, zero out of contact and where the force vanishes."""
    clr_p, jd, Kp, Kv = P.clr_p, X.jd, X.Kp, X.Kv
    for c in range(jd.shape[0]):
        for a in range(2):
            for b in range(2):
                Kp[c, a, b] = 0.0
                Kv[c, a, b] = 0.0
        pen, vn, fn, emag, psi, v0 = jd[c, 0], jd[c, 1], jd[c, 2], jd[c, 3], jd[c, 4], jd[c, 5]
        if not pen > 0.0:
            continue
        p = clr_p[c]
        stiff, expo, ce, law = p[K.CLR_K], p[K.CLR_N], p[K.CLR_CE], int(p[K.CLR_LAW])
        if law == LANKARANI_NIKRAVESH:
            damp = 0.75 * (1.0 - ce * ce) / v0
        elif law == FLORES:
            damp = 1.6 * (1.0 - ce) / ce / v0
        else:
            damp = 0.0
        fac = 1.0 + damp * vn
        if not fac > 0.0:
            continue
        kn = expo * stiff * pen ** (expo - 1.0) * fac  # d fn / d pen
        cn = stiff * pen ** expo * damp  # d fn / d pen rate
        ux, uy = math.cos(psi), math.sin(psi)
        kt = fn / emag if pen > 0.0 and emag > 0.0 else 0.0  # the normal turning with e
        u = (ux, uy)
        for a in range(2):
            for b in range(2):
                uu = u[a] * u[b]
                Kp[c, a, b] = -kn * uu - kt * ((1.0 if a == b else 0.0) - uu)
                Kv[c, a, b] = -cn * uu


@njit(cache=True)
def _small_matrix(X, h):
    """Ms = I - h D (h Kp + Kv) (2 nc x 2 nc)."""
    D, Kp, Kv, Ms = X.D, X.Kp, X.Kv, X.Ms
    r = D.shape[0]
    for a in range(r):
        for b in range(r):
            c = b // 2
            s = 0.0
            for e in range(2):
                s += D[a, 2 * c + e] * (h * Kp[c, e, b % 2] + Kv[c, e, b % 2])
            Ms[a, b] = (1.0 if a == b else 0.0) - h * s


@njit(cache=True)
def _solve_small(A, b, x):
    """x = A^-1 b (Gaussian elimination with partial pivoting on a copy: A is kept)."""
    r = A.shape[0]
    M = A.copy()
    for i in range(r):
        x[i] = b[i]
    for j in range(r):
        piv = j
        for i in range(j + 1, r):
            if abs(M[i, j]) > abs(M[piv, j]):
                piv = i
        if piv != j:
            for c in range(r):
                M[j, c], M[piv, c] = M[piv, c], M[j, c]
            x[j], x[piv] = x[piv], x[j]
        for i in range(j + 1, r):
            f = M[i, j] / M[j, j]
            for c in range(j, r):
                M[i, c] -= f * M[j, c]
            x[i] -= f * x[j]
    for i in range(r - 1, -1, -1):
        s = x[i]
        for c in range(i + 1, r):
            s -= M[i, c] * x[c]
        x[i] = s / M[i, i]


@njit(cache=True)
def _substep(P, X, h, fi, yi):
    """yi += (I - h J)^-1 h fi (Sherman-Morrison-Woodbury on the contacts' two unknowns per joint)."""
    N = yi.shape[0]
    n = N // 2
    clr_b, U, D, Kp, Kv, rz, z, w, gq = P.clr_b, X.U, X.D, X.Kp, X.Kv, X.rz, X.z, X.w, X.gq
    nc = clr_b.shape[0]
    r = 2 * nc
    # r = h fi: rq = h v, rv = h a; w = Kp G rq, rz = G rv + h D Kp G rq
    for c in range(nc):
        for a in range(2):
            gq[2 * c + a] = h * _g_dot(X.G, clr_b, c, a, fi[:n])
    for c in range(nc):
        for a in range(2):
            w[2 * c + a] = Kp[c, a, 0] * gq[2 * c] + Kp[c, a, 1] * gq[2 * c + 1]
    for a in range(r):
        s = 0.0
        for b in range(r):
            s += D[a, b] * w[b]
        c, e = a // 2, a % 2
        rz[a] = h * _g_dot(X.G, clr_b, c, e, fi[n:]) + h * s
    _solve_small(X.Ms, rz, z)
    # w = Kp G rq + (h Kp + Kv) z; dv = rv + h U w; dq = rq + h dv
    for c in range(nc):
        for a in range(2):
            w[2 * c + a] += ((h * Kp[c, a, 0] + Kv[c, a, 0]) * z[2 * c]
                             + (h * Kp[c, a, 1] + Kv[c, a, 1]) * z[2 * c + 1])
    for i in range(n):
        s = 0.0
        for b in range(r):
            s += U[i, b] * w[b]
        dv = h * fi[n + i] + h * s
        yi[n + i] += dv
        yi[i] += h * fi[i] + h * dv


@njit(cache=True)
def liex_try(kc, implicit, t, y, h, k, lamk, speed, P, inc, v0i, ynew, cnew, W, X, atol, rtol):
    """One step of ``kc`` extrapolation columns from (t, y), f(t, y) in k[0]: ynew and, when the error test
    passes, k[2] = f(t + h, ynew), k[1] = (ynew - y) / h, lamk[2] and lamk[1] (the mean of the ends' multipliers:
    linear between them on the Hermite extension) and the Jacobian at ynew for the next step. A step that
    passes the error test but ends in a contact no evaluation of it saw (nor its Jacobian holds) is
    rejected (error norm ONSET_ERROR). Not ``implicit``: J = [[0, I], [0, 0]] (U and D stay zero; the contact
    data are still kept for the onset check). Returns (status, error norm, right-hand sides evaluated)."""
    N = y.shape[0]
    n = N // 2
    nc = cnew.shape[0]
    nf = 0
    jd = X.jd
    if X.tj[0] != t:  # the Jacobian at (t, y) (a rejected step's retry keeps it)
        st = K.accel_inline(t, y[:n], y[n:], speed, P, 0.0, 0.0, inc, v0i, X.f[n:], X.lam, X.cj, W)
        nf += 1
        if st != 0:
            return st, 0.0, nf
        contact_jacobian(y[:n], P, inc, v0i, X.cj, W, X, implicit)
        X.tj[0] = t
    st, err, nfs = _columns(kc, t, y, h, k, speed, P, inc, v0i, ynew, W, X, atol, rtol)
    nf += nfs
    if st != 0 or not err <= 1.0:
        return st, err, nf
    st = K.accel_inline(t + h, ynew[:n], ynew[n:], speed, P, 0.0, 0.0, inc, v0i, k[2, n:], lamk[2], cnew, W)
    nf += 1
    if st != 0:
        return st, 0.0, nf
    for c in range(nc):
        if cnew[c, K.CO_PEN] > 0.0 and jd[c, 0] <= 0.0 and jd[c, 6] <= 0.0:
            return 0, ONSET_ERROR, nf
    for i in range(n):
        k[2, i] = ynew[n + i]
    for i in range(N):
        k[1, i] = (ynew[i] - y[i]) / h
    for r in range(lamk.shape[1]):
        lamk[1, r] = 0.5 * (lamk[0, r] + lamk[2, r])
    contact_jacobian(ynew[:n], P, inc, v0i, cnew, W, X, implicit)
    X.tj[0] = t + h
    return 0, err, nf


@njit(cache=True)
def _columns(kc, t, y, h, k, speed, P, inc, v0i, ynew, W, X, atol, rtol):
    """The extrapolation table of a step (f(t, y) in k[0]): ynew, the error norm and the right-hand sides
    evaluated."""
    N = y.shape[0]
    n = N // 2
    nf = 0
    _stiffness(P, X)
    tab, yi, f, jd = X.tab, X.yi, X.f, X.jd
    for c in range(jd.shape[0]):
        jd[c, 6] = jd[c, 0]
    for j in range(kc):
        nj = j + 1
        hs = h / nj
        _small_matrix(X, hs)
        for i in range(N):
            yi[i] = y[i]
        for s in range(nj):
            if s == 0:
                _substep(P, X, hs, k[0], yi)
            else:
                st = K.accel_inline(t + s * hs, yi[:n], yi[n:], speed, P, 0.0, 0.0, inc, v0i, f[n:], X.lam, X.cj, W)
                nf += 1
                if st != 0:
                    return st, 0.0, nf
                for c in range(jd.shape[0]):
                    jd[c, 6] = max(jd[c, 6], X.cj[c, K.CO_PEN])
                for i in range(n):
                    f[i] = yi[n + i]
                _substep(P, X, hs, f, yi)
        for i in range(N):
            tab[j, 0, i] = yi[i]
        for col in range(1, j + 1):
            den = nj / (nj - col) - 1.0
            for i in range(N):
                tab[j, col, i] = tab[j, col - 1, i] + (tab[j, col - 1, i] - tab[j - 1, col - 1, i]) / den
    err = 0.0
    for i in range(N):
        ynew[i] = tab[kc - 1, kc - 1, i]
        sc = atol[i] + rtol * max(abs(y[i]), abs(ynew[i]))
        err += ((ynew[i] - tab[kc - 1, kc - 2, i]) / sc) ** 2
    return 0, math.sqrt(err / N), nf
