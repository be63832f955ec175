"""Where a journal touches a worn bearing: the contact zones of two worn surfaces, compiled.

The overlap of the journal over the bearing along each global direction, its maximum near the line
of centres (the first zone, with its depths and slopes there), a second load-carrying zone on the
other rim of a bridged pit, and the penetrations of both zones, continuous where the zones merge,
swap or fade. Called by ``kernel.clearance_forces`` through :func:`contact_zones`; imports numpy,
numba, math, ``contact`` and ``midpoints``.

Both searches compare the overlap at the midpoints of the bearing's intervals; :func:`contact_zones`
samples them all once (``midpoints.fill_midpoints``, from tables made once per surface) and both
searches read those samples, so a sample costs a few multiplications instead of two PCHIP
evaluations; every value returned is evaluated from the tables (:func:`overlap_at`'s values, to
rounding). ``worn_contact`` and ``second_zone`` take bare depth arrays and build the tables (O(n)
per call: for tests and tools).
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit
from wearbench.model.surface_tables import (
    depth_eval,
    fill_midpoints,
    midpoint_window,
    region_coordinate,
    rewrap,
    surface_curvature,
    surface_tables,
    table_eval,
)

__all__ = ["SECOND_ZONE_RATIO", "Gap", "Zone", "contact_zones", "overlap_at", "search_second_zone", "search_top_zone",
           "second_zone", "worn_contact", "zone_penetrations"]

# a contact zone: the global direction psi (rad) where the overlap peaks, the overlap f there (m), and
# the worn depths h_b, h_j (m) and their slopes h_b', h_j' (m/rad) of bearing and journal there
# (overlap -inf: no zone)
Zone = namedtuple("Zone", "psi overlap hb hj slope_b slope_j")
# a worn joint at the state as the searches read it beside the surfaces' tables: the region counts of bearing
# and journal, |e| (m) and its direction alpha, the bodies' angles, the clearance (m). Scalars only (the
# tables travel as arguments)
Gap = namedtuple("Gap", "nb nj emag alpha thi thj clear")
# the second zone's walk over the midpoint samples (:func:`search_second_zone`): the gap, the region
# coordinates of alpha, the samples' window, the bearing interval holding the top zone, how far the walk may
# go (half the circle; sample indices t_lo..t_hi; |e| cos down to ec_end; e in the bearing frame (ex, ey)),
# the interval's angle
_Walk = namedtuple("_Walk", "g xb xj i0 m i1 half t_lo t_hi ex ey ec_end cell")


@njit(cache=True, _nrt=False)
def overlap_at(sb, nb, sj, nj, emag, alpha, thi, thj, psi):
    """Radial overlap f(psi) = |e| cos(psi - alpha) - h_b(psi - th_b) - h_j(psi - th_j) (m) of the
    journal over the worn bearing in global direction ``psi``, with df/dpsi and d2f/dpsi2 and the
    two depths and slopes there (see :func:`worn_contact`)."""
    hb, db, d2b = depth_eval(sb, nb, psi - thi)
    hj, dj, d2j = depth_eval(sj, nj, psi - thj)
    return _overlap(emag, psi - alpha, hb, db, d2b, hj, dj, d2j)


@njit(cache=True, inline="always")
def _overlap(emag, dpsi, hb, db, d2b, hj, dj, d2j):
    """The tuple of :func:`overlap_at` from the depths and their derivatives (dpsi = psi - alpha)."""
    c = math.cos(dpsi)
    s = math.sin(dpsi)
    return emag * c - hb - hj, -emag * s - db - dj, -emag * c - d2b - d2j, hb, hj, db, dj


@njit(cache=True, _nrt=False)
def _overlap_tab(tb, tj, nb, nj, emag, alpha, xb, xj, psi):
    """:func:`overlap_at` from ``midpoints.surface_tables``, for |psi - alpha| < 2 pi; ``xb``, ``xj``:
    the region coordinates of alpha on bearing and journal (``contact.region_coordinate``), from
    which an evaluation steps instead of dividing and flooring an angle."""
    d = psi - alpha
    hb, db, d2b = table_eval(tb[0], tb[1], nb, rewrap(xb + d * (nb / (2.0 * math.pi)), nb))
    hj, dj, d2j = table_eval(tj[0], tj[1], nj, rewrap(xj + d * (nj / (2.0 * math.pi)), nj))
    return _overlap(emag, d, hb, db, d2b, hj, dj, d2j)


@njit(cache=True, _nrt=False)
def _off_window(tb, tj, nb, nj, emag, alpha, xb, xj, psi):
    """The overlap at a midpoint ``psi`` outside the sampled window, evaluated (a separate, not
    inlined, function: inlined, it slows the walk's loop tenfold)."""
    return _overlap_tab(tb, tj, nb, nj, emag, alpha, xb, xj, psi)[0]


@njit(cache=True, fastmath=True, _nrt=False)
def _largest(buf, m):
    """max(buf[:m]) (-inf for m = 0); fastmath lets the reduction vectorise (a maximum is exact in
    any order)."""
    top = -math.inf
    for t in range(m):
        top = max(top, buf[t])
    return top


@njit(cache=True, fastmath=True, _nrt=False)
def _above(buf, m, level):
    """The first and last t < m with buf[t] > level ((m, -1) if none); fastmath lets the two
    integer reductions vectorise."""
    lo, hi = m, -1
    for t in range(m):
        v = buf[t] > level
        lo = min(lo, t if v else m)
        hi = max(hi, t if v else -1)
    return lo, hi


@njit(cache=True, inline="always")
def _polish_peak(tb, tj, nb, nj, emag, alpha, xb, xj, psi, ev, cell):
    """The local maximum of the overlap within ``cell`` of ``psi`` (``ev``: the overlap tuple
    there): safeguarded Newton on f' = 0 (bisects across a curvature jump). Returns the point and
    its overlap tuple."""
    lo, hi = psi - cell, psi + cell
    for _ in range(24):
        d1, d2 = ev[1], ev[2]
        if d1 > 0.0:
            lo = psi
        else:
            hi = psi
        nxt = 0.5 * (lo + hi)
        if d2 < 0.0:
            stp = -d1 / d2
            if abs(stp) < 1e-13:  # converged (tested first: psi + stp may round to psi, a bracket end)
                break
            if lo < psi + stp < hi:
                nxt = psi + stp
        if abs(nxt - psi) < 1e-13:
            break
        psi = nxt
        ev = _overlap_tab(tb, tj, nb, nj, emag, alpha, xb, xj, psi)
    return psi, ev


@njit(cache=True, inline="always")
def _zone(psi, ev):
    """The :class:`Zone` at psi from the overlap tuple ``ev`` there (:func:`overlap_at`'s)."""
    return Zone(psi=psi, overlap=ev[0], hb=ev[3], hj=ev[4], slope_b=ev[5], slope_j=ev[6])


@njit(cache=True, inline="always")
def _no_zone(psi):
    """No zone (overlap -inf, depths and slopes zero), at the top zone's direction psi."""
    return Zone(psi=psi, overlap=-math.inf, hb=0.0, hj=0.0, slope_b=0.0, slope_j=0.0)


@njit(cache=True, _nrt=False)
def search_top_zone(tb, tj, g, curv, buf, i0, m):
    """Contact direction of a worn journal in a worn bearing (the :class:`Gap` ``g``; ``tb``, ``tj``: the
    ``midpoints.surface_tables`` of bearing and journal): where the two surfaces overlap most.

    The journal (radius R2 - h_j, journal frame) reaches, in global direction psi from the bearing
    centre, |e| cos(psi - alpha) + R2 - h_j; the bearing wall is at R1 + h_b. The penetration is the
    largest overlap d = max_psi f(psi) - (R1 - R2), f as in :func:`overlap_at` (the tangential offset
    of the journal centre adds (|e| sin)^2 / 2 R2 < 2e-8 m at 0.6 mm / 15 mm and is left out). So a
    circular (or worn) journal rests on the rims of a pit narrower than its relative curvature
    allows instead of sinking to its bottom, and by the envelope theorem grad_e d = u(psi*): the
    normal is the radial direction of the contact point, continuous while the maximum is unique.
    Search: depths are never negative, so f <= |e| cos(psi - alpha): for |e| <= c (the clearance)
    the overlap at alpha is returned. Else the best of the midpoint samples ``buf`` of the window
    (i0, m) (see :func:`contact_zones`; the first of equal ones): both its neighbours are no higher,
    so a local maximum lies within one interval of it, found by safeguarded Newton on f'(psi) = 0.
    Between two midpoints f rises at most sag = (|e| + curv) cell^2 / 8 above the nearer one
    (``curv``: the largest |h_b''| + |h_j''|, ``midpoints.surface_curvature``), so a best sample more
    than sag + 1 um below the clearance is out of contact and returned unpolished. A peak narrower
    than an interval whose samples lie below the best one's can be missed, by at most the sag.
    Returns the :class:`Zone` at the contact direction.
    """
    nb, nj, emag, alpha, thi, thj, clear = g
    xb, xj = region_coordinate(alpha - thi, nb), region_coordinate(alpha - thj, nj)
    if emag <= clear:
        ev = _overlap_tab(tb, tj, nb, nj, emag, alpha, xb, xj, alpha)
        return _zone(alpha, ev)
    cell = 2.0 * math.pi / nb
    top = _largest(buf, m)
    t = 0
    while buf[t] < top:
        t += 1
    best = (i0 + t + 1.0) * cell + thi
    ev = _overlap_tab(tb, tj, nb, nj, emag, alpha, xb, xj, best)
    if ev[0] < clear - (emag + curv) * cell * cell / 8.0 - 1e-6:  # out of contact by a wide margin
        return _zone(best, ev)
    psi, ep = _polish_peak(tb, tj, nb, nj, emag, alpha, xb, xj, best, ev, cell)
    if ep[0] < ev[0]:  # Newton left the best sample's value behind (flat cell): keep the sample
        psi, ep = best, ev
    return _zone(psi, ep)


SECOND_ZONE_RATIO = 0.5  # a second zone counts once its overlap exceeds this fraction of the first's


@njit(cache=True, _nrt=False)
def _walk_side(tb, tj, buf, w, sign, psi1, f1, best):
    """One side (``sign``) of the second zone's walk from the top zone (psi1, f1) over the midpoint
    samples ``buf`` (see :func:`search_second_zone`): ``best`` = (psi, f, valley, valley's midpoint or nan)
    of the highest peak passed so far, returned raised by this side's."""
    nb, nj, emag, alpha, thi = w.g.nb, w.g.nj, w.g.emag, w.g.alpha, w.g.thi
    i0, m, i1, cell = w.i0, w.m, w.i1, w.cell
    best_psi, best_f, best_s, best_s_at = best
    valley, valley_at = f1, math.nan  # valley_at: the midpoint it was sampled at, if any
    prev, prev_psi = f1, psi1
    rising = False
    i = i1 + sign
    k = i % nb  # i modulo nb, kept by steps (an integer division per sample costs more than the sample)
    while abs(i - i1) <= w.half:
        t = i - i0
        past = t > w.t_hi if sign > 0 else t < w.t_lo
        if past or w.ex * tb[2, k] + w.ey * tb[3, k] <= w.ec_end:
            break
        mid = (i + 1.0) * cell + thi
        f = buf[t] if 0 <= t < m else _off_window(tb, tj, nb, nj, emag, alpha, w.xb, w.xj, mid)
        if f < prev:
            if rising and prev > best_f:  # passed a peak at the previous sample
                best_psi, best_f, best_s, best_s_at = prev_psi, prev, valley, valley_at
            rising = False
            if f < valley:
                valley, valley_at = f, mid
        elif f > prev:
            rising = True
        prev, prev_psi = f, mid
        i += sign
        k += sign
        if k == nb:
            k = 0
        elif k < 0:
            k = nb - 1
    if rising and prev > best_f:
        best_psi, best_f, best_s, best_s_at = prev_psi, prev, valley, valley_at
    return best_psi, best_f, best_s, best_s_at


@njit(cache=True, _nrt=False)
def search_second_zone(tb, tj, g, top, buf, i0, m):
    """The second contact zone of a worn joint (the :class:`Gap` ``g``, tables ``tb``, ``tj``): the highest
    local maximum of the overlap f (see :func:`overlap_at`) other than the top one (the :class:`Zone`
    ``top``), and the lowest overlap between the two.

    Walks outward from the top zone over the bearing-interval midpoint samples (``buf``, window (i0, m),
    as :func:`search_top_zone`) on both sides, through valleys and over peaks, while |e| cos(max(0,
    dm - 8 cell)) (dm: angle from alpha) can still reach the floor clear + SECOND_ZONE_RATIO
    (f1 - clear); the highest peak above the floor is polished by safeguarded Newton (it may
    equal f1: two zones of equal overlap). Returns (zone, s): the second :class:`Zone`, its overlap
    -inf (depths and slopes zero) when there is none above the floor; s is the lowest sampled overlap
    on the way from the top zone to it (the saddle, from the interval midpoints; continuous in the
    state, as a minimum of continuous samples, and never below the true saddle; only max(s, clear)
    matters), -inf when there is none.
    """
    nb, nj, emag, alpha, thi, thj, clear = g
    psi1, f1 = top.psi, top.overlap
    none = (_no_zone(psi1), -math.inf)
    floor = clear + SECOND_ZONE_RATIO * (f1 - clear)
    if emag <= floor:
        return none
    cell = 2.0 * math.pi / nb
    xb, xj = region_coordinate(alpha - thi, nb), region_coordinate(alpha - thj, nj)
    reach = math.acos(floor / emag) + 8.0 * cell
    ec_end = emag * math.cos(reach) if reach < 0.5 * math.pi else 0.0  # the walk ends at |e| cos(dm) <= this
    # beyond the outermost samples above the floor no peak can count: the walk stops there (for a
    # window that does not wrap, where the samples hold every midpoint the walk can reach)
    t_lo, t_hi = -nb, m + nb
    if m < nb:
        t_lo, t_hi = _above(buf, m, floor)
    # e in the bearing frame: |e| cos(dm) = e' . (cos, sin)(midpoint); the bearing interval holding psi1
    w = _Walk(g=g, xb=xb, xj=xj, i0=i0, m=m, i1=math.floor((psi1 - thi) / cell - 0.5), half=nb // 2, t_lo=t_lo,
              t_hi=t_hi, ex=emag * math.cos(alpha - thi), ey=emag * math.sin(alpha - thi), ec_end=ec_end, cell=cell)
    best = (psi1, -math.inf, -math.inf, math.nan)
    for sign in (-1, 1):
        best = _walk_side(tb, tj, buf, w, sign, psi1, f1, best)
    best_psi, best_f, best_s, best_s_at = best
    if best_f <= floor:
        return none
    if not math.isnan(best_s_at):  # the saddle and the peak are samples: their values exactly
        best_s = _overlap_tab(tb, tj, nb, nj, emag, alpha, xb, xj, best_s_at)[0]
    eb = _overlap_tab(tb, tj, nb, nj, emag, alpha, xb, xj, best_psi)
    psi, ev = _polish_peak(tb, tj, nb, nj, emag, alpha, xb, xj, best_psi, eb, cell)
    if ev[0] < eb[0]:
        psi, ev = best_psi, eb
    if abs((psi - psi1 + math.pi) % (2.0 * math.pi) - math.pi) < cell:
        return none  # climbed back into the top zone
    return _zone(psi, ev), min(best_s, ev[0])


@njit(cache=True, _nrt=False)
def contact_zones(tb, tj, g, curv, buf):
    """Both contact zones of a worn joint (the :class:`Gap` ``g``; ``tb``, ``tj``: the
    ``midpoints.surface_tables`` of bearing and journal): (top, second, saddle), the
    :class:`Zone` of :func:`search_top_zone` and the zone and saddle of :func:`search_second_zone`
    (second.overlap = -inf: none; searched only when the top zone's overlap exceeds the clearance).
    Samples the overlap at the bearing midpoints within reach once (``midpoints.fill_midpoints``
    into ``buf``, at least nb long) for both. ``curv``: the largest |h_b''| + |h_j''| (m/rad^2,
    ``midpoints.surface_curvature``)."""
    i0, m = midpoint_window(g.nb, g.emag, g.alpha, g.thi, g.clear)
    if g.emag > g.clear:  # else no direction can overlap the clearance: the top zone returns at once
        fill_midpoints(tb, tj, g.nb, g.nj, g.emag, g.alpha, g.thi, g.thj, i0, m, buf)
    top = search_top_zone(tb, tj, g, curv, buf, i0, m)
    second, saddle = _no_zone(top.psi), -math.inf
    if top.overlap > g.clear:
        second, saddle = search_second_zone(tb, tj, g, top, buf, i0, m)
    return top, second, saddle


@njit(cache=True)
def worn_contact(sb, nb, sj, nj, emag, alpha, thi, thj, clear):
    """:func:`search_top_zone` on bare depth arrays (builds the tables: O(n) per call): its :class:`Zone`
    (psi*, f(psi*), h_b, h_j, h_b', h_j')."""
    tb, tj = surface_tables(sb, nb), surface_tables(sj, nj)
    curv = surface_curvature(tb, nb) + surface_curvature(tj, nj)
    g = Gap(nb=nb, nj=nj, emag=emag, alpha=alpha, thi=thi, thj=thj, clear=clear)
    return contact_zones(tb, tj, g, curv, np.empty(nb))[0]


@njit(cache=True)
def second_zone(sb, nb, sj, nj, emag, alpha, thi, thj, clear, psi1, f1):
    """(psi2, f2, saddle) of :func:`search_second_zone` from the top zone (psi1, f1) on bare depth
    arrays (builds the tables: O(n) per call)."""
    tb, tj, buf = surface_tables(sb, nb), surface_tables(sj, nj), np.empty(nb)
    i0, m = midpoint_window(nb, emag, alpha, thi, clear)
    if emag > clear:
        fill_midpoints(tb, tj, nb, nj, emag, alpha, thi, thj, i0, m, buf)
    g = Gap(nb=nb, nj=nj, emag=emag, alpha=alpha, thi=thi, thj=thj, clear=clear)
    top = Zone(psi=psi1, overlap=f1, hb=0.0, hj=0.0, slope_b=0.0, slope_j=0.0)
    zone, saddle = search_second_zone(tb, tj, g, top, buf, i0, m)
    return zone.psi, zone.overlap, saddle


@njit(cache=True, _nrt=False)
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
