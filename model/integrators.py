"""Time integrators for scenes with freedoms: one compiled step for every tableau, one compiled loop.

:func:`erk_try` steps any explicit Runge-Kutta tableau of ``methods.py`` (the methods are data
there); :func:`run_loop` is shared by all of them: step control, projection, contact-mode
updates, dense output, contact records, peaks, each accepted step's bookkeeping in a small
compiled helper. ``k[0] = f(t, y)`` on entry to a step and ``k[scheme.end] = f`` at its end (the
tableau owns its stage count). :func:`kinematics_loop` serves fully driven scenes with ideal joints.
The loop runs compiled, returning to Python only when done, when a record buffer is full or on
failure, so a step costs no interpreter time. Imports numpy, numba and the model's kernel only.

State y = (q, v); f(t, y) = (v, a) with a from :func:`wearbench.model.kernel.accel`.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit
from wearbench.model import kernel as K
from wearbench.model.contact import impact_speed

__all__ = ["STATS", "Control", "Model", "Output", "Track", "deriv", "erk_try", "kinematics_loop", "new_stats", "run_loop",
           "sensor_acc"]

# loop status codes
DONE, SINGULAR, NO_PROJECTION, NOT_FINITE, STEP_COLLAPSE, DRIFT, FULL, BLOW_UP, TOO_MANY_STEPS, PAUSED = range(10)
# the loop's statistics and saved state, one record (``stats = new_stats()``, fields read as stats[0].steps or
# stats["steps"][0]): accepted and rejected steps, largest position and velocity drift, time, next step,
# output samples and contact records filled, the joint or coordinate and the value of a failure, function
# evaluations, peak searches, the step controller's previous error
STATS = np.dtype([(name, np.float64) for name in ("steps", "rejected", "drift_p", "drift_v", "t", "h", "out", "rec",
                                                  "detail", "nfev", "value", "peak_searches", "err_old")])
# peak tracking: a local maximum of an endpoint sequence above this fraction of the running peak is
# searched for on the dense output of the two steps around it
PEAK_SEARCH_FRACTION = 0.8
_GOLDEN_ITERATIONS = 24  # golden-section iterations per step searched: the bracket shrinks by 0.618**24
NREC = 8  # t, dt, fn, vt, omega_rel, phi_bearing, phi_journal, pen

# step control of run_loop: adaptive step, projection (and its tolerance), drift limit, atol (per
# coordinate), rtol, smallest and largest step, accepted steps per call
Control = namedtuple("Control", "adaptive project proj_tol drift_tol atol rtol hmin hmax max_steps")
# peak tracking of run_loop (see its docstring): sensor, running peaks, previous step's pk, pe, pst
Track = namedtuple("Track", "sensor peaks pk pe pst")
# what run_loop fills: output times and, per time, state, accelerations, contact outputs and multipliers;
# contact records (one row per accepted step and clearance joint) when ``record``; ``evaluate``: each
# sample's accelerations and multipliers from a right-hand side at the interpolated state (else from the
# tableau's continuous extension, when it has one and the method no Baumgarte stabilisation)
Output = namedtuple("Output", "t y a c lam rec record evaluate")
# the mechanism as the loop evaluates it: parameters, motor speed, Baumgarte (alpha, beta), contact modes
# (inc, v0i), blow-up penetration per joint, the kernel's workspace
Model = namedtuple("Model", "P speed alpha beta inc v0i blow_pen W")


def new_stats() -> np.ndarray:
    """A zeroed statistics record (:data:`STATS`) for :func:`run_loop`."""
    return np.zeros(1, STATS)


@njit(cache=True)
def deriv(t, y, speed, P, alpha, beta, inc, v0i, dy, lam, cout, W):
    """f(t, y) = (v, a) into dy, the multipliers into lam, the contact outputs into cout; returns the
    kernel's status (:func:`_deriv`, compiled into the stages of :func:`erk_try`)."""
    return _deriv(t, y, speed, P, alpha, beta, inc, v0i, dy, lam, cout, W)


@njit(cache=True, inline="always")
def _deriv(t, y, speed, P, alpha, beta, inc, v0i, dy, lam, cout, W):
    n = y.shape[0] // 2
    q = y[:n]
    v = y[n:]
    st = K.accel_inline(t, q, v, speed, P, alpha, beta, inc, v0i, dy[n:], lam, cout, W)
    for i in range(n):
        dy[i] = v[i]
    return st


@njit(cache=True)
def erk_try(scheme, t, y, h, k, speed, P, alpha, beta, inc, v0i, ynew, ytmp, lamk, cout, W, atol, rtol):
    """One step of an explicit Runge-Kutta tableau: ynew and k[scheme.end] = f(t + h, ynew), the
    multipliers of stage s in lamk[s]; returns (status, error norm), the norm 0 for a method without an
    embedded estimate."""
    N = y.shape[0]
    A, B, C, last = scheme.a, scheme.b, scheme.c, scheme.end
    # the stages, then (without FSAL) f at the new state as stage ``last``: one evaluation site, compiled in
    for s in range(1, last + 1):
        if s < scheme.stages:
            for i in range(N):
                acc = 0.0
                for r in range(s):
                    acc += A[s, r] * k[r, i]
                ytmp[i] = y[i] + h * acc
            ts, ys = t + C[s] * h, ytmp
        else:
            for i in range(N):
                acc = 0.0
                for r in range(scheme.stages):
                    acc += B[r] * k[r, i]
                ynew[i] = y[i] + h / scheme.b_den * acc
            ts, ys = t + h, ynew
        st = _deriv(ts, ys, speed, P, alpha, beta, inc, v0i, k[s], lamk[s], cout, W)
        if st != 0:
            return st, 0.0
    if scheme.fsal:
        for i in range(N):
            ynew[i] = ytmp[i]
    E = scheme.e
    if E.shape[0] == 0:
        return 0, 0.0
    err = 0.0
    for i in range(N):
        e = 0.0
        for r in range(E.shape[0]):
            e += E[r] * k[r, i]
        sc = atol[i] + rtol * max(abs(y[i]), abs(ynew[i]))
        err += (h * e / sc) ** 2
    return 0, math.sqrt(err / N)


@njit(cache=True)
def _hermite(t0, y0, f0, t1, y1, f1, t, out):
    h = t1 - t0
    s = (t - t0) / h
    h00 = (1 + 2 * s) * (1 - s) ** 2
    h10 = s * (1 - s) ** 2
    h01 = s * s * (3 - 2 * s)
    h11 = s * s * (s - 1)
    for i in range(y0.shape[0]):
        out[i] = h00 * y0[i] + h * h10 * f0[i] + h01 * y1[i] + h * h11 * f1[i]


@njit(cache=True)
def sensor_acc(y, f, sensor):
    """|acceleration| of the sensor point along its axis from the state y and f = (v, a); 0 without
    a sensor. sensor = (body index or -1, x, y in the body, axis angle in the body)."""
    b = int(sensor[0])
    if b < 0:
        return 0.0
    n = y.shape[0] // 2
    i, j = 3 * b, n + 3 * b
    _, _, acc = K.point_along(y[i], y[i + 1], y[i + 2], y[j], y[j + 1], y[j + 2], f[j], f[j + 1], f[j + 2],
                              sensor[1], sensor[2], sensor[3])
    return abs(acc)


@njit(cache=True)
def _peak_values(t, y, speed, P, inc, v0i, f, lam, cout, W, sensor, vals):
    """The tracked quantities at (t, y) without stabilisation, as the output table has them:
    normal contact force per clearance joint, then |sensor acceleration|."""
    deriv(t, y, speed, P, 0.0, 0.0, inc, v0i, f, lam, cout, W)
    nc = cout.shape[0]
    for c in range(nc):
        vals[c] = cout[c, K.CO_FN]
    vals[nc] = sensor_acc(y, f, sensor)


@njit(cache=True)
def _golden_max(j, t0, y0, f0, t1, y1, f1, speed, P, inc, v0i, yo, fo, lam, cout, W, sensor, vals):
    """Largest value of tracked quantity j on the step's dense output (cubic Hermite on [t0, t1])
    by golden-section search (one evaluation per iteration)."""
    g = 0.6180339887498949
    a, b = t0, t1
    c, d = b - g * (b - a), a + g * (b - a)
    _hermite(t0, y0, f0, t1, y1, f1, c, yo)
    _peak_values(c, yo, speed, P, inc, v0i, fo, lam, cout, W, sensor, vals)
    fc = vals[j]
    _hermite(t0, y0, f0, t1, y1, f1, d, yo)
    _peak_values(d, yo, speed, P, inc, v0i, fo, lam, cout, W, sensor, vals)
    fd = vals[j]
    for _ in range(_GOLDEN_ITERATIONS):
        if fc > fd:
            b, d, fd = d, c, fc
            c = b - g * (b - a)
            _hermite(t0, y0, f0, t1, y1, f1, c, yo)
            _peak_values(c, yo, speed, P, inc, v0i, fo, lam, cout, W, sensor, vals)
            fc = vals[j]
        else:
            a, c, fc = c, d, fd
            d = a + g * (b - a)
            _hermite(t0, y0, f0, t1, y1, f1, d, yo)
            _peak_values(d, yo, speed, P, inc, v0i, fo, lam, cout, W, sensor, vals)
            fd = vals[j]
    return max(fc, fd)


@njit(cache=True)
def _extension(D, y, h, k, th, yo, fo, dbs):
    """The continuous extension (coefficients D) of a step of length h from y with stages k at theta:
    the state y + h sum_i b_i(theta) k_i into yo, its time derivative sum_i b_i'(theta) k_i into fo (the
    velocities: the state's own), the b_i'(theta) into dbs. Returns nothing; b_i, b_i' of a stage that is
    zero are skipped."""
    N = y.shape[0]
    n = N // 2
    for i in range(N):
        yo[i] = y[i]
        fo[i] = 0.0
    for s in range(D.shape[0]):
        b = 0.0
        db = 0.0
        p = th
        dp = 1.0
        for j in range(D.shape[1]):
            b += D[s, j] * p
            db += (j + 1) * D[s, j] * dp
            dp = p
            p *= th
        dbs[s] = db
        if b == 0.0 and db == 0.0:
            continue
        hb = h * b
        for i in range(N):
            yo[i] += hb * k[s, i]
        for i in range(n, N):
            fo[i] += db * k[s, i]
    for i in range(n):
        fo[i] = yo[n + i]


@njit(cache=True)
def _extension_values(D, mdl, t0, y0, h, k, ts, yo, fo, cout, sensor, vals, dbs):
    """The tracked quantities (as :func:`_peak_values`) at ts on a step's continuous extension: normal
    contact forces from the force law at the interpolated state, |sensor acceleration| from its derivative."""
    _extension(D, y0, h, k, (ts - t0) / h, yo, fo, dbs)
    n = y0.shape[0] // 2
    K.clearance_forces(yo[:n], yo[n:], mdl.P, mdl.inc, mdl.v0i, mdl.W, cout)
    nc = cout.shape[0]
    for c in range(nc):
        vals[c] = cout[c, K.CO_FN]
    vals[nc] = sensor_acc(yo, fo, sensor)


@njit(cache=True)
def _golden_max_ext(j, D, mdl, t0, y0, h, k, yo, fo, cout, sensor, vals, dbs):
    """Largest value of tracked quantity j on a step's continuous extension (as :func:`_golden_max`)."""
    g = 0.6180339887498949
    a, b = t0, t0 + h
    c, d = b - g * (b - a), a + g * (b - a)
    _extension_values(D, mdl, t0, y0, h, k, c, yo, fo, cout, sensor, vals, dbs)
    fc = vals[j]
    _extension_values(D, mdl, t0, y0, h, k, d, yo, fo, cout, sensor, vals, dbs)
    fd = vals[j]
    for _ in range(_GOLDEN_ITERATIONS):
        if fc > fd:
            b, d, fd = d, c, fc
            c = b - g * (b - a)
            _extension_values(D, mdl, t0, y0, h, k, c, yo, fo, cout, sensor, vals, dbs)
            fc = vals[j]
        else:
            a, c, fc = c, d, fd
            d = a + g * (b - a)
            _extension_values(D, mdl, t0, y0, h, k, d, yo, fo, cout, sensor, vals, dbs)
            fd = vals[j]
    return max(fc, fd)


@njit(cache=True)
def _update_modes(cout_old, cout_new, inc, v0i):
    """Contact onset/loss per clearance joint after an accepted step; True if a mode changed.

    The impact speed is the normal speed interpolated to the zero crossing of the penetration."""
    changed = False
    for c in range(inc.shape[0]):
        p0 = cout_old[c, K.CO_PEN]
        p1 = cout_new[c, K.CO_PEN]
        if p1 > 0.0 and inc[c] == 0:
            f = p0 / (p0 - p1) if p0 < 0.0 else 0.0
            vn = cout_old[c, K.CO_VN] + f * (cout_new[c, K.CO_VN] - cout_old[c, K.CO_VN])
            v0i[c] = impact_speed(vn)
            inc[c] = 1
            changed = True
        elif p1 <= 0.0 and inc[c] != 0:
            inc[c] = 0
            changed = True
    return changed


@njit(cache=True, inline="always")
def _save(st, status, t, h, iout, irec, err_old):
    """The loop's state in the statistics record ``st`` (a later call goes on from it); returns ``status``."""
    st.t = t
    st.h = h
    st.out = iout
    st.rec = irec
    st.err_old = err_old
    return status


@njit(cache=True)
def _fail(st, status, t, detail, value):
    """A failure at time t in the statistics record (the joint or coordinate involved, the value); returns status."""
    st.t = t
    if detail >= 0:
        st.detail = detail
    if not math.isnan(value):
        st.value = value
    return status


@njit(cache=True)
def _accept(scheme, control, mdl, t, hh, t_new, ynew, k, lam, cnew, st):
    """Checks and projection of a step accepted by the error test: finite state, drift (projected when
    measurable, then f at the end evaluated again), drift limit and blow-up. Returns a status."""
    N = ynew.shape[0]
    n = N // 2
    P, W = mdl.P, mdl.W
    for i in range(N):
        if not math.isfinite(ynew[i]):
            return _fail(st, NOT_FINITE, t + hh, i, ynew[i])
    if t_new == t + hh:  # the step's last evaluation left the constraints at (t_new, ynew) in W
        dp, dv = K.drift_of(P, ynew[n:], W)
    else:
        dp, dv = K.drift(t_new, ynew[:n], ynew[n:], mdl.speed, P, W)
    if control.project and (dp > 10.0 * control.proj_tol or dv > 1e3 * control.proj_tol):
        # project only when the drift is measurable: the FSAL derivative stays valid otherwise
        ps = K.project(t_new, ynew[:n], ynew[n:], mdl.speed, P, W, control.proj_tol, 4)
        if ps != 0:
            return _fail(st, NO_PROJECTION if ps == K.NO_CONVERGENCE else SINGULAR, t_new, -1, math.nan)
        status = deriv(t_new, ynew, mdl.speed, P, mdl.alpha, mdl.beta, mdl.inc, mdl.v0i, k[scheme.end], lam, cnew, W)
        st.nfev += 1
        if status != 0:
            return _fail(st, SINGULAR, t_new, -1, math.nan)
        dp, dv = K.drift_of(P, ynew[n:], W)  # that evaluation left the constraints at (t_new, ynew) in W
    st.drift_p = max(st.drift_p, dp)
    st.drift_v = max(st.drift_v, dv)
    if dp > control.drift_tol:
        return _fail(st, DRIFT, t_new, -1, dp)
    for c in range(cnew.shape[0]):
        if cnew[c, K.CO_PEN] > mdl.blow_pen[c]:
            return _fail(st, BLOW_UP, t_new, c, cnew[c, K.CO_PEN])
    return DONE


@njit(cache=True)
def _track_peaks(mdl, track, t, y, f0, t_new, ynew, f1, lam, cnew, st, yo, fo, csamp, enew, vals, D, k, dbs):
    """Running peaks over the step just accepted: the tracked values at its end (evaluated again under
    Baumgarte stabilisation), and where the previous end was a local maximum near the running peak, the
    golden-section search of the dense output of this step and (modes unchanged) the previous one: the
    continuous extension D with the stages k where D has rows (the table's own interpolant), else cubic
    Hermite with a right-hand side per point. pk keeps the previous step's ends, f there and stages."""
    sensor, peaks, pk, pe, pst = track
    P, W, speed, inc, v0i = mdl.P, mdl.W, mdl.speed, mdl.inc, mdl.v0i
    nc = cnew.shape[0]
    nq = nc + 1
    # values at the step's end with its modes, without stabilisation (as the output samples)
    if mdl.alpha == 0.0 and mdl.beta == 0.0:
        for c in range(nc):
            enew[c] = cnew[c, K.CO_FN]
        enew[nc] = sensor_acc(ynew, f1, sensor)
    else:
        _peak_values(t_new, ynew, speed, P, inc, v0i, fo, lam, csamp, W, sensor, enew)
        st.nfev += 1
    for j in range(nq):
        peaks[j] = max(peaks[j], enew[j])
        e = pe[1, j]
        if (e > enew[j] and e > 0.0 and e >= PEAK_SEARCH_FRACTION * peaks[j]
                and (pst[2] < 2 or e >= pe[0, j])):
            # a local maximum at t: the peak lies in this step or, modes unchanged, the previous one
            if D.shape[0] > 0:
                v = _golden_max_ext(j, D, mdl, t, y, t_new - t, k, yo, fo, csamp, sensor, vals, dbs)
            else:
                v = _golden_max(j, t, y, f0, t_new, ynew, f1, speed, P, inc, v0i, yo, fo, lam, csamp, W, sensor,
                                vals)
                st.nfev += _GOLDEN_ITERATIONS + 2
            peaks[j] = max(peaks[j], v)
            if pst[2] >= 2 and pst[3] == 0.0:
                if D.shape[0] > 0:
                    v = _golden_max_ext(j, D, mdl, pst[0], pk[0], pst[1] - pst[0], pk[4:], yo, fo, csamp, sensor,
                                        vals, dbs)
                else:
                    v = _golden_max(j, pst[0], pk[0], pk[1], pst[1], pk[2], pk[3], speed, P, inc, v0i, yo, fo,
                                    lam, csamp, W, sensor, vals)
                    st.nfev += _GOLDEN_ITERATIONS + 2
                peaks[j] = max(peaks[j], v)
            st.peak_searches += 1
    for j in range(nq):
        pe[0, j] = pe[1, j]
        pe[1, j] = enew[j]
    for i in range(y.shape[0]):
        pk[0, i] = y[i]
        pk[1, i] = f0[i]
        pk[2, i] = ynew[i]
        pk[3, i] = f1[i]
    for r in range(D.shape[0]):
        for i in range(y.shape[0]):
            pk[4 + r, i] = k[r, i]
    pst[0] = t
    pst[1] = t_new
    pst[2] = min(pst[2] + 1.0, 2.0)


@njit(cache=True, inline="always")
def _copy_rows(dst, src):
    """dst[:] = src for 2-d arrays as a plain loop (numba's slice assignment costs ~40 ns per call)."""
    for c in range(src.shape[0]):
        for x in range(src.shape[1]):
            dst[c, x] = src[c, x]


@njit(cache=True, inline="always")
def _store_sample(out, iout, yo, fo, csamp, peaks, sensor):
    """Output sample iout: state, accelerations, contact outputs; the running peaks raised by its values."""
    n = yo.shape[0] // 2
    nc = csamp.shape[0]
    oy, oa = out.y[iout], out.a[iout]
    for i in range(2 * n):
        oy[i] = yo[i]
    for i in range(n):
        oa[i] = fo[n + i]
    _copy_rows(out.c[iout], csamp)
    for c in range(nc):
        peaks[c] = max(peaks[c], csamp[c, K.CO_FN])
    peaks[nc] = max(peaks[nc], sensor_acc(yo, fo, sensor))


@njit(cache=True)
def _dense_output(mdl, out, sensor, peaks, iout, t, y, f0, t_new, ynew, f1, yo, fo, csamp):
    """Output samples on (t, t_new] by cubic Hermite interpolation of y with the modes of the step, f and
    the contact outputs evaluated there (their peaks tracked too); returns the next sample's index."""
    N = y.shape[0]
    out_t = out.t
    while iout < out_t.shape[0] and out_t[iout] <= t_new:
        ts = out_t[iout]
        if ts <= t:
            for i in range(N):
                yo[i] = y[i]
        elif ts >= t_new:
            for i in range(N):
                yo[i] = ynew[i]
        else:
            _hermite(t, y, f0, t_new, ynew, f1, ts, yo)
        deriv(ts, yo, mdl.speed, mdl.P, 0.0, 0.0, mdl.inc, mdl.v0i, fo, out.lam[iout], csamp, mdl.W)
        _store_sample(out, iout, yo, fo, csamp, peaks, sensor)
        iout += 1
    return iout


@njit(cache=True)
def _dense_output_stages(scheme, mdl, out, sensor, peaks, iout, t, y, h, t_new, ynew, k, lamk, yo, fo, csamp,
                         dbs):
    """Output samples on (t, t_new] from the tableau's continuous extension (``scheme.d``) of the step
    of length h: the state y + h sum_i b_i(theta) k_i, the accelerations and multipliers as its time
    derivative sum_i b_i'(theta) (k_i, lamk_i) (the stages' values combined: no solve), the contact
    outputs from the force law at the state with the step's modes (their peaks tracked too); the step's
    end itself takes its evaluated values. Returns the next sample's index. dbs: work array, one entry per row of
    ``scheme.d``."""
    N = y.shape[0]
    n = N // 2
    m = lamk.shape[1]
    D = scheme.d
    ns = D.shape[0]
    out_t = out.t
    end = scheme.end
    while iout < out_t.shape[0] and out_t[iout] <= t_new:
        ts = out_t[iout]
        lo = out.lam[iout]
        if ts >= t_new or ts <= t:
            src = end if ts >= t_new else 0
            ysrc = ynew if ts >= t_new else y
            for i in range(N):
                yo[i] = ysrc[i]
                fo[i] = k[src, i]
            for r in range(m):
                lo[r] = lamk[src, r]
        else:
            th = (ts - t) / h
            _extension(D, y, h, k, th, yo, fo, dbs)
            for r in range(m):
                lo[r] = 0.0
            for s in range(ns):
                db = dbs[s]
                if db != 0.0:
                    for r in range(m):
                        lo[r] += db * lamk[s, r]
        K.clearance_forces(yo[:n], yo[n:], mdl.P, mdl.inc, mdl.v0i, mdl.W, csamp)
        _store_sample(out, iout, yo, fo, csamp, peaks, sensor)
        iout += 1
    return iout


@njit(cache=True)
def _record(rec, irec, t, t_new, cnew):
    """One contact record per clearance joint for the step (t, t_new]."""
    for c in range(cnew.shape[0]):
        r = rec[irec, c]
        r[0] = t_new
        r[1] = t_new - t
        r[2] = cnew[c, K.CO_FN]
        r[3] = cnew[c, K.CO_VT]
        r[4] = cnew[c, K.CO_OMEGA]
        r[5] = cnew[c, K.CO_PHIB]
        r[6] = cnew[c, K.CO_PHIJ]
        r[7] = cnew[c, K.CO_PEN]


@njit(cache=True, inline="always")
def _raise_peaks(peaks, values):
    for j in range(peaks.shape[0]):
        peaks[j] = max(peaks[j], values[j])


@njit(cache=True, inline="always")
def _next_step(hh, err, err_old, factor_max, hmax, expo_pi):
    """PI step control after an accepted step (Hairer, Wanner: Solving ODE I, sec. II.4, beta = 0.04):
    the next step and the error remembered for the next one."""
    e = max(err, 1e-10)
    f = 0.9 * e ** -expo_pi * err_old ** 0.04
    return min(hmax, hh * min(factor_max, max(0.2, f))), max(e, 1e-4)


@njit(cache=True)
def run_loop(scheme, control, mdl, t, y, h, t_end, out, k, cout_old, stats, track):
    """Integrate from t to t_end (in place on y, the modes mdl.inc and mdl.v0i, and ``stats``) with the
    tableau ``scheme`` (:class:`~wearbench.model.methods.Scheme`) under the step control ``control``
    (:class:`Control`) for the mechanism ``mdl`` (:class:`Model`), filling ``out`` (:class:`Output`) and
    tracking peaks in ``track`` (:class:`Track`).

    Output samples out.t[stats.out:] falling in each accepted step are filled by cubic Hermite
    interpolation of y, then f and the contact outputs are evaluated there. With ``out.record`` each
    accepted step appends one row per clearance joint to out.rec (stops with FULL when it is full).
    peaks (in/out): running maxima of the normal force per clearance joint and of |sensor
    acceleration| (``sensor`` as in :func:`sensor_acc`) over the dense output, not only the output
    samples: where the values at the step ends have a local maximum (above PEAK_SEARCH_FRACTION of
    the running peak), the two steps around it are searched (:func:`_golden_max`). pk, pe, ps carry
    the previous step (its ends and f there, the end values, [t0, t1, steps known, mode changed])
    across calls; pst starts at zeros. k[0] holds f(t, y) on entry, k[scheme.end] f at a step's end.
    After ``control.max_steps`` accepted steps it returns PAUSED with its state saved (call again to go
    on: the steps taken do not depend on the pauses). Returns a status code; stats' detail holds the
    joint or coordinate involved, its value the offending value.
    """
    st = stats[0]
    sensor, peaks, pe, pst = track.sensor, track.peaks, track.pe, track.pst
    P, W, speed, alpha, beta, inc, v0i = mdl.P, mdl.W, mdl.speed, mdl.alpha, mdl.beta, mdl.inc, mdl.v0i
    N = y.shape[0]
    end = scheme.end
    ynew = np.empty(N)
    ytmp = np.empty(N)
    yo = np.empty(N)
    fo = np.empty(N)
    lam = np.empty(out.lam.shape[1])
    lamk = np.empty((end + 1, out.lam.shape[1]))
    stages_out = scheme.d.shape[0] > 0 and alpha == 0.0 and beta == 0.0 and not out.evaluate
    no_stages = np.zeros((0, scheme.d.shape[1]))
    cnew = np.empty_like(cout_old)
    csamp = np.empty_like(cout_old)
    iout = int(st.out)
    irec = int(st.rec)
    nsteps = 0
    factor_max = 5.0
    err_old = st.err_old if st.err_old > 0.0 else 1e-4
    enew = np.empty(inc.shape[0] + 1)
    vals = np.empty(inc.shape[0] + 1)
    dbs = np.empty(scheme.d.shape[0])
    if pst[2] == 0:  # values at the start
        _peak_values(t, y, speed, P, inc, v0i, fo, lam, csamp, W, sensor, pe[1])
        _raise_peaks(peaks, pe[1])
        pst[2] = 1
    if stages_out:  # the multipliers at the start (k[0] holds f there)
        deriv(t, y, speed, P, alpha, beta, inc, v0i, fo, lamk[0], csamp, W)
        st.nfev += 1
    while t < t_end:
        if out.record and irec >= out.rec.shape[0]:
            return _save(st, FULL, t, h, iout, irec, err_old)
        hh = min(h, t_end - t)
        last = hh >= t_end - t
        status, err = erk_try(scheme, t, y, hh, k, speed, P, alpha, beta, inc, v0i, ynew, ytmp, lamk, cnew, W,
                              control.atol, control.rtol)
        st.nfev += scheme.nfev
        if status != 0:
            return _fail(st, SINGULAR, t, -1, math.nan)
        if not math.isfinite(err):
            err = 1e10
        if control.adaptive and err > 1.0:
            st.rejected += 1
            h = hh * max(0.2, 0.9 * err ** -scheme.expo)
            factor_max = 1.0
            if h < control.hmin:
                st.h = h
                return _fail(st, STEP_COLLAPSE, t, -1, math.nan)
            continue
        t_new = t_end if last else t + hh
        status = _accept(scheme, control, mdl, t, hh, t_new, ynew, k, lamk[end], cnew, st)
        if status != DONE:
            return status
        _track_peaks(mdl, track, t, y, k[0], t_new, ynew, k[end], lam, cnew, st, yo, fo, csamp, enew, vals,
                     scheme.d if stages_out else no_stages, k, dbs)
        if stages_out:
            iout = _dense_output_stages(scheme, mdl, out, sensor, peaks, iout, t, y, hh, t_new, ynew, k, lamk, yo,
                                        fo, csamp, dbs)
        else:
            iout = _dense_output(mdl, out, sensor, peaks, iout, t, y, k[0], t_new, ynew, k[end], yo, fo, csamp)
        pst[3] = 0.0
        if _update_modes(cout_old, cnew, inc, v0i):
            deriv(t_new, ynew, speed, P, alpha, beta, inc, v0i, k[end], lamk[end], cnew, W)
            st.nfev += 1
            pst[3] = 1.0
        if out.record:
            _record(out.rec, irec, t, t_new, cnew)
            irec += 1
        for i in range(N):
            y[i] = ynew[i]
            k[0, i] = k[end, i]
        for r in range(lamk.shape[1]):
            lamk[0, r] = lamk[end, r]
        _copy_rows(cout_old, cnew)
        t = t_new
        nsteps += 1
        st.steps += 1
        if control.adaptive:
            h, err_old = _next_step(hh, err, err_old, factor_max, control.hmax, scheme.expo_pi)
            factor_max = 5.0
        if nsteps >= control.max_steps and t < t_end:  # back to Python now and then (Ctrl-C); call again
            return _save(st, PAUSED, t, h, iout, irec, err_old)
    return _save(st, DONE, t, h, iout, irec, err_old)


@njit(cache=True)
def kinematics_loop(times, q, v, speed, P, W, tol, out_y, out_a, out_lam, out_c, stats):
    """Position, velocity and acceleration analysis plus inverse dynamics at each of ``times``.

    For a fully driven mechanism with ideal joints: Newton on Phi(q, t) = 0 from a second-order
    predictor, velocities from Phi_q v = nu, then accelerations and multipliers (joint reactions)
    from eq. 30 without stabilisation. Returns 0 or a kernel status; stats' t the failing time.
    """
    record = stats[0]
    n = q.shape[0]
    inc = np.zeros(0, np.int64)
    v0i = np.zeros(0)
    a = np.zeros(n)
    t_prev = times[0] if times.shape[0] else 0.0
    for i in range(times.shape[0]):
        t = times[i]
        dt = t - t_prev
        for j in range(n):
            q[j] += v[j] * dt + 0.5 * a[j] * dt * dt
            v[j] += a[j] * dt
        st = K.project(t, q, v, speed, P, W, tol, 30)
        if st != 0:
            record.t = t
            return st
        st = K.accel(t, q, v, speed, P, 0.0, 0.0, inc, v0i, a, out_lam[i], out_c[i], W)
        if st != 0:
            record.t = t
            return st
        out_y[i, :n] = q
        out_y[i, n:] = v
        out_a[i] = a
        record.steps += 1
        t_prev = t
    return 0
