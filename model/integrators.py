"""Time integrators for scenes with freedoms: one compiled step for every tableau, one compiled loop.

:func:`erk_try` steps any explicit Runge-Kutta tableau of ``methods.py`` (the methods are data
there); :func:`run_loop` is shared by all of them: step control, projection, contact-mode
updates, dense output, contact records, peaks, each accepted step's bookkeeping in a small
compiled helper. ``k[0] = f(t, y)`` on entry to a step and ``k[scheme.end] = f`` at its end (the
tableau owns its stage count). :func:`kinematics_loop` serves fully driven scenes with ideal joints.
The loop runs compiled, returning to Python only when done, when a record buffer is full or on
failure, so a step costs no interpreter time. What crosses into the loop are named records built by
keyword on the Python side: the mechanism (``kernel.Model``), :class:`Control`, :class:`Output` and
the peak tracker :func:`new_track` builds. Imports numpy, numba and the model's kernel only.

Everything the steps run is compiled without numba's reference counting (``_nrt=False``): only
:func:`run_loop` and :func:`kinematics_loop` allocate; the functions they call allocate nothing and
return no array, so the counts numba would take and give back on every array a record holds or a
view makes (a locked instruction each; a third of a run's time) protect nothing. The same holds for
the right-hand side (``kernel``) and the worn-contact search (``worn_contact``). A function compiled so
that allocated would not compile; one that returned an array would hand its caller an uncounted one.

State y = (q, v); f(t, y) = (v, a) with a from :func:`wearbench.model.kernel.accel`.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit
from wearbench.model import kernel as K
from wearbench.model.contact import impact_speed
from wearbench.model.methods import Scheme

__all__ = ["GOLDEN_ITERATIONS", "NREC", "PEAK_SEARCH_FRACTION", "PEAK_STATE", "STATS", "Control", "Output", "Track",
           "deriv", "erk_try", "extension", "kinematics_loop", "new_stats", "new_track", "next_step", "run_loop",
           "sensor_acc", "update_modes"]

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
GOLDEN_ITERATIONS = 24  # golden-section iterations per step searched: the bracket shrinks by 0.618**24
NREC = 8  # t, dt, fn, vt, omega_rel, phi_bearing, phi_journal, pen
# Newton iterations of the projection after a step and of the kinematics' position analysis: numpy
# integers, not literals, so these callers share the one compiled kernel.project (a literal argument
# compiles a copy of its own)
_STEP_PROJECTION_ITERATIONS = np.int64(4)
_KINEMATICS_ITERATIONS = np.int64(30)

# step control of run_loop: adaptive step, projection (and its tolerance), drift limit, blow-up penetration per
# clearance joint (m), atol (per coordinate), rtol, smallest and largest step, accepted steps per call
Control = namedtuple("Control", "adaptive project proj_tol drift_tol blow_pen atol rtol hmin hmax max_steps")
# peak tracking of run_loop (see its docstring), carried across its calls; built by :func:`new_track`:
# the sensor, the running peaks, and the previous accepted step: ``prev`` its arrays (rows PREV_*),
# ``values`` the tracked values at the last two step ends (rows 0: the earlier, 1: the last), ``state`` a
# :data:`PEAK_STATE` record
Track = namedtuple("Track", "sensor peaks prev values state")
# rows of Track.prev: the previous step's start state and f there, its end state and f there, then its
# stages (the tableau's stage array k) from row PREV_STAGES on
PREV_Y0, PREV_F0, PREV_Y1, PREV_F1, PREV_STAGES = range(5)
# the previous step as the peak search knows it: its start and end times, how many steps are known
# (0: none, not even the start's values; 1: the start's values; 2: a whole step) and whether the contact
# modes changed at its end (its dense output then does not continue into the next step's)
PEAK_STATE = np.dtype([("t0", np.float64), ("t1", np.float64), ("known", np.int64), ("changed", np.int64)])
# what run_loop fills: output times and, per time, the state's and accelerations' recorded entries (indices
# ``ycols`` of y, ``acols`` of the accelerations: what the table reads, not the whole state), contact
# outputs and multipliers; contact records (one row per accepted step and clearance joint) when
# ``record``; ``evaluate``: each sample's accelerations and multipliers from a right-hand side at the
# interpolated state (else from the tableau's continuous extension, when it has one and the method no
# Baumgarte stabilisation)
Output = namedtuple("Output", "t y a c lam rec record evaluate ycols acols")
# one step: start time, state and f there, end time, state and f there
_Ends = namedtuple("_Ends", "t0 y0 f0 t1 y1 f1")
# the loop's work arrays: a sample's state (yo) and f there (fo), multipliers (lam), contact outputs (csamp),
# the tracked values at a step's end (enew) and at a search point (vals), continuous-extension weights (dbs)
_Scratch = namedtuple("_Scratch", "yo fo lam csamp enew vals dbs")
# what one call of run_loop works with: the tableau, step control, the mechanism as given and without
# stabilisation (plain: the samples' and peaks' right-hand side), output, peak tracker, statistics, work
# arrays, the continuous extension the peak search uses (no rows: cubic Hermite), whether the output
# samples come from it and whether the steps run under Baumgarte stabilisation. The step's helpers are
# compiled into the loop (inline)
_Loop = namedtuple("_Loop", "scheme control mdl plain out track stats s D stages_out stabilised")


def new_stats() -> np.ndarray:
    """A zeroed statistics record (:data:`STATS`) for :func:`run_loop`."""
    return np.zeros(1, STATS)


def new_track(sensor: np.ndarray, joints: int, scheme: Scheme, size: int) -> Track:
    """A fresh peak tracker (:class:`Track`) for :func:`run_loop`: ``sensor`` as in :func:`sensor_acc`,
    ``joints`` clearance joints, the tableau's ``scheme`` (its stage rows) and the state's ``size``."""
    return Track(sensor=sensor, peaks=np.zeros(joints + 1), prev=np.zeros((PREV_STAGES + scheme.end + 1, size)),
                 values=np.zeros((2, joints + 1)), state=np.zeros(1, PEAK_STATE))


@njit(cache=True, _nrt=False)
def deriv(t, y, mdl, dy, lam, cout):
    """f(t, y) = (v, a) of the mechanism ``mdl`` (``kernel.Model``) into dy, the multipliers into lam, the
    contact outputs into cout; returns the kernel's status. For the samples, peak searches and
    re-evaluations: a call of :func:`kernel.accel`, which the kinematics share (compiled once, cached),
    while the steps' stages (:func:`erk_try`) have the right-hand side compiled in (:func:`_deriv`)."""
    n = y.shape[0] // 2
    v = y[n:]
    st = K.accel(t, y[:n], v, mdl, dy[n:], lam, cout)
    for i in range(n):
        dy[i] = v[i]
    return st


@njit(cache=True, inline="always")
def _deriv(t, y, speed, P, W, stab, inc, v0i, dy, lam, cout):
    n = y.shape[0] // 2
    q = y[:n]
    v = y[n:]
    st = K.accel_arrays(t, q, v, speed, P, W, stab, inc, v0i, dy[n:], lam, cout)
    for i in range(n):
        dy[i] = v[i]
    return st


@njit(cache=True, inline="always")
def _unstabilised(mdl):
    """``mdl`` without Baumgarte stabilisation (alpha = beta = 0), sharing its arrays."""
    return K.Model(P=mdl.P, speed=mdl.speed, alpha=0.0, beta=0.0, inc=mdl.inc, v0i=mdl.v0i, W=mdl.W)


@njit(cache=True, _nrt=False)
def erk_try(scheme, control, mdl, t, y, h, k, ynew, ytmp, lamk, cout):
    """One step of an explicit Runge-Kutta tableau for the mechanism ``mdl`` (``kernel.Model``): ynew and
    k[scheme.end] = f(t + h, ynew), the multipliers of stage s in lamk[s]; returns (status, error norm)
    under ``control``'s atol and rtol, the norm 0 for a method without an embedded estimate."""
    N = y.shape[0]
    A, B, C, last = scheme.a, scheme.b, scheme.c, scheme.end
    atol, rtol = control.atol, control.rtol
    # the record's parts once per step
    speed, P, W, stab, inc, v0i = mdl.speed, mdl.P, mdl.W, (mdl.alpha, mdl.beta), mdl.inc, mdl.v0i
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
        st = _deriv(ts, ys, speed, P, W, stab, inc, v0i, k[s], lamk[s], cout)
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


@njit(cache=True, _nrt=False)
def _hermite(e, t, out):
    """Cubic Hermite interpolation of the step ``e`` (:data:`_Ends`) at t into out."""
    t0, y0, f0, t1, y1, f1 = e
    h = t1 - t0
    s = (t - t0) / h
    h00 = (1 + 2 * s) * (1 - s) ** 2
    h10 = s * (1 - s) ** 2
    h01 = s * s * (3 - 2 * s)
    h11 = s * s * (s - 1)
    for i in range(y0.shape[0]):
        out[i] = h00 * y0[i] + h * h10 * f0[i] + h01 * y1[i] + h * h11 * f1[i]


@njit(cache=True, inline="always")
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


@njit(cache=True, _nrt=False)
def _peak_values(t, y, plain, sensor, s, vals):
    """The tracked quantities at (t, y) into vals, without stabilisation (``plain``), as the output table
    has them: normal contact force per clearance joint, then |sensor acceleration| (f, multipliers and
    contact outputs into the work arrays ``s``)."""
    deriv(t, y, plain, s.fo, s.lam, s.csamp)
    nc = s.csamp.shape[0]
    for c in range(nc):
        vals[c] = s.csamp[c, K.CO_FN]
    vals[nc] = sensor_acc(y, s.fo, sensor)


@njit(cache=True, _nrt=False)
def _golden_max(j, e, plain, sensor, s):
    """Largest value of tracked quantity j on the step's dense output (cubic Hermite on the step ``e``)
    by golden-section search (one evaluation per iteration)."""
    g = 0.6180339887498949
    a, b = e.t0, e.t1
    c, d = b - g * (b - a), a + g * (b - a)
    vals = s.vals
    _hermite(e, c, s.yo)
    _peak_values(c, s.yo, plain, sensor, s, vals)
    fc = vals[j]
    _hermite(e, d, s.yo)
    _peak_values(d, s.yo, plain, sensor, s, vals)
    fd = vals[j]
    for _ in range(GOLDEN_ITERATIONS):
        if fc > fd:
            b, d, fd = d, c, fc
            c = b - g * (b - a)
            _hermite(e, c, s.yo)
            _peak_values(c, s.yo, plain, sensor, s, vals)
            fc = vals[j]
        else:
            a, c, fc = c, d, fd
            d = a + g * (b - a)
            _hermite(e, d, s.yo)
            _peak_values(d, s.yo, plain, sensor, s, vals)
            fd = vals[j]
    return max(fc, fd)


@njit(cache=True, inline="always")
def extension(D, y, h, k, th, yo, fo, dbs):
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


@njit(cache=True, _nrt=False)
def _extension_values(D, plain, t0, y0, h, k, ts, sensor, s):
    """The tracked quantities (as :func:`_peak_values`, into s.vals) at ts on a step's continuous extension:
    normal contact forces from the force law at the interpolated state, |sensor acceleration| from its
    derivative."""
    extension(D, y0, h, k, (ts - t0) / h, s.yo, s.fo, s.dbs)
    n = y0.shape[0] // 2
    K.clearance_forces(s.yo[:n], s.yo[n:], plain, s.csamp, False)
    nc = s.csamp.shape[0]
    for c in range(nc):
        s.vals[c] = s.csamp[c, K.CO_FN]
    s.vals[nc] = sensor_acc(s.yo, s.fo, sensor)


@njit(cache=True, _nrt=False)
def _golden_max_ext(j, D, plain, t0, y0, h, k, sensor, s):
    """Largest value of tracked quantity j on a step's continuous extension (as :func:`_golden_max`)."""
    g = 0.6180339887498949
    a, b = t0, t0 + h
    c, d = b - g * (b - a), a + g * (b - a)
    vals = s.vals
    _extension_values(D, plain, t0, y0, h, k, c, sensor, s)
    fc = vals[j]
    _extension_values(D, plain, t0, y0, h, k, d, sensor, s)
    fd = vals[j]
    for _ in range(GOLDEN_ITERATIONS):
        if fc > fd:
            b, d, fd = d, c, fc
            c = b - g * (b - a)
            _extension_values(D, plain, t0, y0, h, k, c, sensor, s)
            fc = vals[j]
        else:
            a, c, fc = c, d, fd
            d = a + g * (b - a)
            _extension_values(D, plain, t0, y0, h, k, d, sensor, s)
            fd = vals[j]
    return max(fc, fd)


@njit(cache=True, _nrt=False)
def update_modes(cout_old, cout_new, inc, v0i):
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


@njit(cache=True, inline="always")
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
        ps = K.project(t_new, ynew[:n], ynew[n:], mdl.speed, P, W, control.proj_tol, _STEP_PROJECTION_ITERATIONS)
        if ps != 0:
            return _fail(st, NO_PROJECTION if ps == K.NO_CONVERGENCE else SINGULAR, t_new, -1, math.nan)
        status = deriv(t_new, ynew, mdl, k[scheme.end], lam, cnew)
        st.nfev += 1
        if status != 0:
            return _fail(st, SINGULAR, t_new, -1, math.nan)
        dp, dv = K.drift_of(P, ynew[n:], W)  # that evaluation left the constraints at (t_new, ynew) in W
    st.drift_p = max(st.drift_p, dp)
    st.drift_v = max(st.drift_v, dv)
    if dp > control.drift_tol:
        return _fail(st, DRIFT, t_new, -1, dp)
    for c in range(cnew.shape[0]):
        if cnew[c, K.CO_PEN] > control.blow_pen[c]:
            return _fail(st, BLOW_UP, t_new, c, cnew[c, K.CO_PEN])
    return DONE


@njit(cache=True, inline="always")
def _search_step(j, D, plain, e, k, sensor, s, st):
    """Largest value of tracked quantity j over the step ``e``: on the continuous extension D with the
    step's stages k where D has rows (the tableau's own interpolant), else on cubic Hermite with a
    right-hand side per point (counted in st.nfev)."""
    if D.shape[0] > 0:
        return _golden_max_ext(j, D, plain, e.t0, e.y0, e.t1 - e.t0, k, sensor, s)
    st.nfev += GOLDEN_ITERATIONS + 2
    return _golden_max(j, e, plain, sensor, s)


@njit(cache=True, inline="always")
def _track_peaks(stabilised, plain, track, e, cnew, st, s, D, k):
    """Running peaks over the step ``e`` just accepted: the tracked values at its end (evaluated again
    under Baumgarte stabilisation), and where the previous end was a local maximum near the running peak,
    the golden-section search (:func:`_search_step`) of the dense output of this step and (modes
    unchanged) the previous one. ``track.prev`` keeps the previous step's ends, f there and stages.
    ``stabilised``: the steps run under Baumgarte stabilisation."""
    sensor, peaks, prev, pe = track.sensor, track.peaks, track.prev, track.values
    ps = track.state[0]
    nc = cnew.shape[0]
    nq = nc + 1
    enew = s.enew
    # values at the step's end with its modes, without stabilisation (as the output samples)
    if not stabilised:
        for c in range(nc):
            enew[c] = cnew[c, K.CO_FN]
        enew[nc] = sensor_acc(e.y1, e.f1, sensor)
    else:
        _peak_values(e.t1, e.y1, plain, sensor, s, enew)
        st.nfev += 1
    for j in range(nq):
        peaks[j] = max(peaks[j], enew[j])
        last = pe[1, j]
        if (last > enew[j] and last > 0.0 and last >= PEAK_SEARCH_FRACTION * peaks[j]
                and (ps.known < 2 or last >= pe[0, j])):
            # a local maximum at the step's start: the peak lies in this step or, modes unchanged, the previous one
            peaks[j] = max(peaks[j], _search_step(j, D, plain, e, k, sensor, s, st))
            if ps.known >= 2 and ps.changed == 0:
                before = _Ends(t0=ps.t0, y0=prev[PREV_Y0], f0=prev[PREV_F0], t1=ps.t1, y1=prev[PREV_Y1],
                               f1=prev[PREV_F1])
                peaks[j] = max(peaks[j], _search_step(j, D, plain, before, prev[PREV_STAGES:], sensor, s, st))
            st.peak_searches += 1
    for j in range(nq):
        pe[0, j] = pe[1, j]
        pe[1, j] = enew[j]
    for i in range(e.y0.shape[0]):
        prev[PREV_Y0, i] = e.y0[i]
        prev[PREV_F0, i] = e.f0[i]
        prev[PREV_Y1, i] = e.y1[i]
        prev[PREV_F1, i] = e.f1[i]
    for r in range(D.shape[0]):
        for i in range(e.y0.shape[0]):
            prev[PREV_STAGES + r, i] = k[r, i]
    ps.t0 = e.t0
    ps.t1 = e.t1
    ps.known = min(ps.known + 1, 2)


@njit(cache=True, inline="always")
def _copy_rows(dst, src):
    """dst[:] = src for 2-d arrays as a plain loop (numba's slice assignment costs ~40 ns per call)."""
    for c in range(src.shape[0]):
        for x in range(src.shape[1]):
            dst[c, x] = src[c, x]


@njit(cache=True, inline="always")
def _store_sample(out_y, out_a, out_c, iout, yo, fo, csamp, peaks, sensor, ycols, acols):
    """Output sample iout (rows of the output's y, a and c, indexed in place) from the work arrays: the
    recorded entries (``ycols``, ``acols``) of the state and the accelerations, the contact outputs; the
    running peaks raised by its values. The caller takes the arrays from their records once for all its
    samples."""
    n = yo.shape[0] // 2
    nc = csamp.shape[0]
    for j in range(ycols.shape[0]):
        out_y[iout, j] = yo[ycols[j]]
    for j in range(acols.shape[0]):
        out_a[iout, j] = fo[n + acols[j]]
    for c in range(nc):
        for x in range(csamp.shape[1]):
            out_c[iout, c, x] = csamp[c, x]
    for c in range(nc):
        peaks[c] = max(peaks[c], csamp[c, K.CO_FN])
    peaks[nc] = max(peaks[nc], sensor_acc(yo, fo, sensor))


@njit(cache=True, _nrt=False)
def _dense_output(plain, out, track, iout, e, s):
    """Output samples on the step ``e`` (t0, t1] by cubic Hermite interpolation of y with the modes of the
    step, f and the contact outputs evaluated there (their peaks tracked too); returns the next sample's
    index."""
    N = e.y0.shape[0]
    yo, fo, csamp, peaks, sensor = s.yo, s.fo, s.csamp, track.peaks, track.sensor
    out_t, out_y, out_a, out_c, out_lam, ycols, acols = out.t, out.y, out.a, out.c, out.lam, out.ycols, out.acols
    while iout < out_t.shape[0] and out_t[iout] <= e.t1:
        ts = out_t[iout]
        if ts <= e.t0:
            for i in range(N):
                yo[i] = e.y0[i]
        elif ts >= e.t1:
            for i in range(N):
                yo[i] = e.y1[i]
        else:
            _hermite(e, ts, yo)
        deriv(ts, yo, plain, fo, out_lam[iout], csamp)
        _store_sample(out_y, out_a, out_c, iout, yo, fo, csamp, peaks, sensor, ycols, acols)
        iout += 1
    return iout


@njit(cache=True, inline="always")
def _dense_output_stages(scheme, plain, out, track, iout, e, h, k, lamk, s):
    """Output samples on the step ``e`` (t0, t1] of length h from the tableau's continuous extension
    (``scheme.d``): the state y + h sum_i b_i(theta) k_i, the accelerations and multipliers as its time
    derivative sum_i b_i'(theta) (k_i, lamk_i) (the stages' values combined: no solve), the contact
    outputs from the force law at the state with the step's modes (their peaks tracked too); the step's
    end itself takes its evaluated values. Returns the next sample's index."""
    t, y, t_new, ynew = e.t0, e.y0, e.t1, e.y1
    # the arrays taken from their records, and the views made, once for the step's samples
    yo, fo, dbs, csamp, peaks, sensor = s.yo, s.fo, s.dbs, s.csamp, track.peaks, track.sensor
    P, W, inc, v0i = plain.P, plain.W, plain.inc, plain.v0i
    out_t, out_y, out_a, out_c, out_lam, ycols, acols = out.t, out.y, out.a, out.c, out.lam, out.ycols, out.acols
    N = y.shape[0]
    n = N // 2
    qo, vo = yo[:n], yo[n:]
    m = lamk.shape[1]
    D = scheme.d
    ns = D.shape[0]
    end = scheme.end
    while iout < out_t.shape[0] and out_t[iout] <= t_new:
        ts = out_t[iout]
        if ts >= t_new or ts <= t:
            src = end if ts >= t_new else 0
            ysrc = ynew if ts >= t_new else y
            for i in range(N):
                yo[i] = ysrc[i]
                fo[i] = k[src, i]
            for r in range(m):
                out_lam[iout, r] = lamk[src, r]
        else:
            th = (ts - t) / h
            extension(D, y, h, k, th, yo, fo, dbs)
            for r in range(m):
                out_lam[iout, r] = 0.0
            for s_ in range(ns):
                db = dbs[s_]
                if db != 0.0:
                    for r in range(m):
                        out_lam[iout, r] += db * lamk[s_, r]
        K.clearance_arrays(qo, vo, P, W, inc, v0i, csamp, False)
        _store_sample(out_y, out_a, out_c, iout, yo, fo, csamp, peaks, sensor, ycols, acols)
        iout += 1
    return iout


@njit(cache=True, _nrt=False)
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
def next_step(hh, err, err_old, factor_max, hmax, expo_pi):
    """PI step control after an accepted step (Hairer, Wanner: Solving ODE I, sec. II.4, beta = 0.04):
    the next step and the error remembered for the next one."""
    e = max(err, 1e-10)
    f = 0.9 * e ** -expo_pi * err_old ** 0.04
    return min(hmax, hh * min(factor_max, max(0.2, f))), max(e, 1e-4)


@njit(cache=True, inline="always")
def _begin(L, t, y, lamk):
    """At a call's start: the tracked values at the run's start (on its first call) and, for samples from
    the stages, the multipliers at t (k[0] holds f there) into lamk[0]."""
    track, s, st = L.track, L.s, L.stats[0]
    ps = track.state[0]
    if ps.known == 0:  # values at the start
        _peak_values(t, y, L.plain, track.sensor, s, track.values[1])
        _raise_peaks(track.peaks, track.values[1])
        ps.known = 1
    if L.stages_out:  # the multipliers at the start (k[0] holds f there)
        deriv(t, y, L.mdl, s.fo, lamk[0], s.csamp)
        st.nfev += 1


@njit(cache=True, inline="always")
def _after_accept(L, iout, irec, e, hh, k, lamk, cout_old, cnew):
    """An accepted step ``e`` of length hh, checked and projected: its peaks, output samples, contact-mode
    changes (f and the multipliers at its end evaluated again with the new modes) and contact records.
    Returns the next output sample's and contact record's indices."""
    st, end = L.stats[0], L.scheme.end
    _track_peaks(L.stabilised, L.plain, L.track, e, cnew, st, L.s, L.D, k)
    if L.stages_out:
        iout = _dense_output_stages(L.scheme, L.plain, L.out, L.track, iout, e, hh, k, lamk, L.s)
    else:
        iout = _dense_output(L.plain, L.out, L.track, iout, e, L.s)
    ps = L.track.state[0]
    ps.changed = 0
    if update_modes(cout_old, cnew, L.mdl.inc, L.mdl.v0i):
        deriv(e.t1, e.y1, L.mdl, k[end], lamk[end], cnew)
        st.nfev += 1
        ps.changed = 1
    if L.out.record:
        _record(L.out.rec, irec, e.t0, e.t1, cnew)
        irec += 1
    return iout, irec


@njit(cache=True, inline="always")
def _advance(end, y, ynew, k, lamk, cout_old, cnew):
    """The accepted step's end becomes the next step's start: y, k[0] = f, the multipliers, the contact outputs."""
    for i in range(y.shape[0]):
        y[i] = ynew[i]
        k[0, i] = k[end, i]
    for r in range(lamk.shape[1]):
        lamk[0, r] = lamk[end, r]
    _copy_rows(cout_old, cnew)


@njit(cache=True)
def run_loop(scheme, control, mdl, t, y, h, t_end, out, k, cout_old, stats, track):
    """Integrate from t to t_end (in place on y, the modes mdl.inc and mdl.v0i, and ``stats``) with the
    tableau ``scheme`` (:class:`~wearbench.model.methods.Scheme`) under the step control ``control``
    (:class:`Control`) for the mechanism ``mdl`` (``kernel.Model``), filling ``out`` (:class:`Output`) and
    tracking peaks in ``track`` (:class:`Track`, from :func:`new_track`).

    Output samples out.t[stats.out:] falling in each accepted step are filled by cubic Hermite
    interpolation of y, then f and the contact outputs are evaluated there (or from the tableau's
    continuous extension, see :class:`Output`). With ``out.record`` each accepted step appends one row
    per clearance joint to out.rec (stops with FULL when it is full). track.peaks (in/out): running
    maxima of the normal force per clearance joint and of |sensor acceleration| (``track.sensor`` as in
    :func:`sensor_acc`) over the dense output, not only the output samples: where the values at the
    step ends have a local maximum (above PEAK_SEARCH_FRACTION of the running peak), the two steps
    around it are searched (:func:`_golden_max`). The rest of ``track`` carries the previous step across
    calls. k[0] holds f(t, y) on entry, k[scheme.end] f at a step's end.
    After ``control.max_steps`` accepted steps it returns PAUSED with its state saved (call again to go
    on: the steps taken do not depend on the pauses). Returns a status code; stats' detail holds the
    joint or coordinate involved, its value the offending value.
    """
    N = y.shape[0]
    nq = mdl.inc.shape[0] + 1
    s = _Scratch(yo=np.empty(N), fo=np.empty(N), lam=np.empty(out.lam.shape[1]), csamp=np.empty_like(cout_old),
                 enew=np.empty(nq), vals=np.empty(nq), dbs=np.empty(scheme.d.shape[0]))
    lamk = np.empty((scheme.end + 1, out.lam.shape[1]))
    stabilised = mdl.alpha != 0.0 or mdl.beta != 0.0
    stages_out = scheme.d.shape[0] > 0 and not stabilised and not out.evaluate
    D = scheme.d if stages_out else np.zeros((0, scheme.d.shape[1]))
    L = _Loop(scheme=scheme, control=control, mdl=mdl, plain=_unstabilised(mdl), out=out, track=track, stats=stats,
              s=s, D=D, stages_out=stages_out, stabilised=stabilised)
    return _steps(L, t, y, h, t_end, k, cout_old, np.empty(N), np.empty(N), lamk, np.empty_like(cout_old))


@njit(cache=True, _nrt=False)
def _steps(L, t, y, h, t_end, k, cout_old, ynew, ytmp, lamk, cnew):
    """:func:`run_loop`'s steps, on the work arrays it made (the step's new state and stage input, the
    stages' multipliers, the new contact outputs); compiled without reference counting (module docstring)."""
    scheme, control, mdl, out, st = L.scheme, L.control, L.mdl, L.out, L.stats[0]
    end = scheme.end
    iout = int(st.out)
    irec = int(st.rec)
    nsteps = 0
    factor_max = 5.0
    err_old = st.err_old if st.err_old > 0.0 else 1e-4
    _begin(L, t, y, lamk)
    while t < t_end:
        if out.record and irec >= out.rec.shape[0]:
            return _save(st, FULL, t, h, iout, irec, err_old)
        hh = min(h, t_end - t)
        last = hh >= t_end - t
        status, err = erk_try(scheme, control, mdl, t, y, hh, k, ynew, ytmp, lamk, cnew)
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
        step = _Ends(t0=t, y0=y, f0=k[0], t1=t_new, y1=ynew, f1=k[end])
        iout, irec = _after_accept(L, iout, irec, step, hh, k, lamk, cout_old, cnew)
        _advance(end, y, ynew, k, lamk, cout_old, cnew)
        t = t_new
        nsteps += 1
        st.steps += 1
        if control.adaptive:
            h, err_old = next_step(hh, err, err_old, factor_max, control.hmax, scheme.expo_pi)
            factor_max = 5.0
        if nsteps >= control.max_steps and t < t_end:  # back to Python now and then (Ctrl-C); call again
            return _save(st, PAUSED, t, h, iout, irec, err_old)
    return _save(st, DONE, t, h, iout, irec, err_old)


@njit(cache=True)
def kinematics_loop(out, q, v, speed, P, W, tol, stats):
    """Position, velocity and acceleration analysis plus inverse dynamics at each of the output's times
    (:data:`Output`: its recorded entries of the state and accelerations, multipliers, contact outputs).

    For a fully driven mechanism with ideal joints: Newton on Phi(q, t) = 0 from a second-order
    predictor, velocities from Phi_q v = nu, then accelerations and multipliers (joint reactions)
    from eq. 30 without stabilisation. Returns 0 or a kernel status; stats' t the failing time.
    """
    record = stats[0]
    times, out_y, out_a, out_lam, out_c, ycols, acols = out.t, out.y, out.a, out.lam, out.c, out.ycols, out.acols
    n = q.shape[0]
    mdl = K.Model(P=P, speed=speed, alpha=0.0, beta=0.0, inc=np.zeros(0, np.int64), v0i=np.zeros(0), W=W)
    a = np.zeros(n)
    t_prev = times[0] if times.shape[0] else 0.0
    for i in range(times.shape[0]):
        t = times[i]
        dt = t - t_prev
        for j in range(n):
            q[j] += v[j] * dt + 0.5 * a[j] * dt * dt
            v[j] += a[j] * dt
        st = K.project(t, q, v, speed, P, W, tol, _KINEMATICS_ITERATIONS)
        if st != 0:
            record.t = t
            return st
        st = K.accel(t, q, v, mdl, a, out_lam[i], out_c[i])
        if st != 0:
            record.t = t
            return st
        for j in range(ycols.shape[0]):
            c = ycols[j]
            out_y[i, j] = q[c] if c < n else v[c - n]
        for j in range(acols.shape[0]):
            out_a[i, j] = a[acols[j]]
        record.steps += 1
        t_prev = t
    return 0
