"""Where a journal touches a worn bearing: the contact zones of two worn surfaces, compiled.

The overlap of the journal over the bearing along each global direction, its maximum near the line
of centres (the first zone, with its depths and slopes there), a second load-carrying zone on the
other rim of a bridged pit, and the penetrations of both zones, continuous where the zones merge,
swap or fade. Called by ``kernel.clearance_forces``; imports numpy, numba, math and ``contact``.

Both searches sample the overlap at the midpoints of the bearing's intervals (between two region
centres). The kernel passes each surface with its table of PCHIP node slopes (``contact.node_slopes``,
computed once per surface when the scene is packed), so a sample costs a few multiplications: the
bearing's midpoint depth is the Hermite value at fraction 1/2, the journal's a table lookup, and
|e| cos(psi - alpha) is rotated from one midpoint to the next (re-anchored every 16 samples) instead
of evaluated. ``worn_contact`` and ``second_zone`` take bare depth arrays and build the tables.
"""

from __future__ import annotations

import math

from numba import njit
from wearbench.model.contact import depth_eval, midpoint_depth, node_slopes, table_depth

__all__ = ["SECOND_ZONE_RATIO", "overlap_at", "search_second_zone", "search_top_zone", "second_zone",
           "worn_contact", "zone_penetrations"]

_ANCHOR = 16  # midpoint samples between two exact evaluations of cos/sin (rotation in between)


@njit(cache=True)
def overlap_at(sb, nb, sj, nj, emag, alpha, thi, thj, psi):
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
def _mid_overlap(sb, mb, nb, sj, mj, nj, i, ec, xj):
    """Overlap (m) at the midpoint of bearing interval ``i`` (between centres i and i + 1), given
    ``ec`` = |e| cos(midpoint - alpha) and ``xj``, the journal's region coordinate there."""
    return ec - midpoint_depth(sb, mb, nb, i) - table_depth(sj, mj, nj, xj)


@njit(cache=True)
def _interval_bound(sb, nb, sj, nj, emag, alpha, thj, rj, lo_b, cell, i):
    """Upper bound of the overlap on bearing interval ``i`` (global angles [lo_b, lo_b + cell]):
    |e| max cos - the smaller bearing node - the smallest journal node under it."""
    hi_b = lo_b + cell
    d = 0.0 if lo_b <= alpha <= hi_b else min(abs(lo_b - alpha), abs(hi_b - alpha))
    return emag * math.cos(d) - min(sb[i % nb], sb[(i + 1) % nb]) - _node_min(
        sj, nj, (lo_b - thj) * rj - 0.5, (hi_b - thj) * rj - 0.5)


@njit(cache=True, inline="always")
def _polish_peak(sb, nb, sj, nj, emag, alpha, thi, thj, psi, cell):
    """The local maximum of the overlap within ``cell`` of ``psi``: safeguarded Newton on f' = 0
    (bisects across a curvature jump)."""
    lo, hi = psi - cell, psi + cell
    for _ in range(24):
        d1, d2 = overlap_at(sb, nb, sj, nj, emag, alpha, thi, thj, psi)[1:3]
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
def search_top_zone(sb, mb, nb, sj, mj, nj, emag, alpha, thi, thj, clear, hint):
    """Contact direction of a worn journal in a worn bearing: where the two surfaces overlap most.

    The journal (radius R2 - h_j, journal frame) reaches, in global direction psi from the bearing
    centre, |e| cos(psi - alpha) + R2 - h_j; the bearing wall is at R1 + h_b. The penetration is the
    largest overlap d = max_psi f(psi) - (R1 - R2), f as in :func:`overlap_at` (the tangential offset
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
    then Newton on f'(psi) = 0 around the best point. ``mb``, ``mj``: the surfaces' node slopes
    (``contact.node_slopes``); the midpoints of a block that passes its bound are all sampled (from
    the tables, cheaper than bounding each interval) and a sample is taken as the best exactly
    when the interval's bound would have let it be.
    Returns (psi*, f(psi*), h_b, h_j, h_b', h_j') at the contact direction.
    """
    f0, d1, d2, hb0, hj0, sb0, sj0 = overlap_at(sb, nb, sj, nj, emag, alpha, thi, thj, alpha)
    if emag <= max(f0, clear):
        return alpha, f0, hb0, hj0, sb0, sj0
    cell = 2.0 * math.pi / nb
    # 1. climb to the local maximum next to alpha (a good first bound prunes most of the scan)
    best, fbest = alpha, f0
    dh = (hint - alpha + math.pi) % (2.0 * math.pi) - math.pi
    if abs(dh) < 0.5 * math.pi:  # the last contact direction is usually next to this one
        fh, h1, h2 = overlap_at(sb, nb, sj, nj, emag, alpha, thi, thj, alpha + dh)[:3]
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
        f, e1, e2 = overlap_at(sb, nb, sj, nj, emag, alpha, thi, thj, best + stp)[:3]
        for _ in range(3):
            if f > fbest:
                break
            stp *= 0.25
            f, e1, e2 = overlap_at(sb, nb, sj, nj, emag, alpha, thi, thj, best + stp)[:3]
        if f <= fbest:
            break
        best, fbest, d1, d2 = best + stp, f, e1, e2
        if abs(stp) < 1e-4 * cell:
            break
    # 2. branch and bound over blocks of bearing intervals, outward from alpha
    rj = nj / (2.0 * math.pi)
    rot_c, rot_s = math.cos(cell), math.sin(cell)
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
                c = math.cos(lo_g + 0.5 * cell - alpha)
                s = math.sin(lo_g + 0.5 * cell - alpha)
                for i in range(first, first + blk):
                    lo_b = (i + 0.5) * cell + thi
                    psi = lo_b + 0.5 * cell
                    f = _mid_overlap(sb, mb, nb, sj, mj, nj, i, emag * c, (psi - thj) * rj - 0.5)
                    c, s = c * rot_c - s * rot_s, s * rot_c + c * rot_s
                    # as if each interval were bounded first: one below the clearance is sampled
                    # only if its bound beats it (out of contact, where the best is not polished)
                    if f > fbest and (f > clear or _interval_bound(sb, nb, sj, nj, emag, alpha, thj, rj,
                                                                   lo_b, cell, i) > clear):
                        best, fbest = psi, f
            first += sign * blk
    if fbest < clear - 1e-6:  # no contact by a wide margin: its exact place does not matter
        f, _, _, hb, hj, db, dj = overlap_at(sb, nb, sj, nj, emag, alpha, thi, thj, best)
        return best, f, hb, hj, db, dj
    fbest = overlap_at(sb, nb, sj, nj, emag, alpha, thi, thj, best)[0]  # a table sample: exactly
    psi = _polish_peak(sb, nb, sj, nj, emag, alpha, thi, thj, best, cell)
    f, _, _, hb, hj, db, dj = overlap_at(sb, nb, sj, nj, emag, alpha, thi, thj, psi)
    if f < fbest:  # Newton left the best sample's value behind (flat cell): keep the sample
        psi = best
        f, _, _, hb, hj, db, dj = overlap_at(sb, nb, sj, nj, emag, alpha, thi, thj, psi)
    return psi, f, hb, hj, db, dj


@njit(cache=True)
def worn_contact(sb, nb, sj, nj, emag, alpha, thi, thj, clear, hint):
    """:func:`search_top_zone` on bare depth arrays (builds the node-slope tables: O(n) per call)."""
    return search_top_zone(sb, node_slopes(sb, nb), nb, sj, node_slopes(sj, nj), nj, emag, alpha, thi, thj,
                           clear, hint)


SECOND_ZONE_RATIO = 0.5  # a second zone counts once its overlap exceeds this fraction of the first's


@njit(cache=True)
def search_second_zone(sb, mb, nb, sj, mj, nj, emag, alpha, thi, thj, clear, psi1, f1):
    """The second contact zone of a worn joint: the highest local maximum of the overlap f (see
    :func:`overlap_at`) other than the top one (psi1, f1), and the lowest overlap between the two.

    Walks outward from psi1 over bearing-interval midpoints on both sides, through valleys and
    over peaks, while |e| cos can still reach the floor clear + SECOND_ZONE_RATIO (f1 - clear),
    skipping blocks of 8 intervals whose upper bound (|e| max cos - min node depths) cannot reach
    the clearance (tried where the last sample was below the clearance, at most once per 8 samples:
    a skip only saves work, the result is the same as sampling); the highest peak above the floor is polished by safeguarded Newton (it may
    equal f1: two zones of equal overlap). ``mb``, ``mj``: node slopes as in :func:`search_top_zone`.
    Returns (psi2, f2, s) with
    f2 = -inf when there is no second zone above the floor; s is the lowest sampled overlap on the
    way from psi1 to psi2 (the saddle, from the interval midpoints; continuous in the state, as a
    minimum of continuous samples, and never below the true saddle; when it is below the
    clearance only that matters, as ``zone_penetrations`` uses max(s, clear)).
    """
    floor = clear + SECOND_ZONE_RATIO * (f1 - clear)
    if emag <= floor:
        return psi1, -math.inf, -math.inf
    cell = 2.0 * math.pi / nb
    rj = nj / (2.0 * math.pi)
    rot_c = math.cos(cell)
    # the walk ends where |e| cos(max(0, dm - 8 cell)) <= floor or dm >= pi/2 (dm: angle from
    # alpha), i.e. where cos(dm) <= cos_end
    reach = math.acos(floor / emag) + 8.0 * cell
    cos_end = math.cos(reach) if reach < 0.5 * math.pi else 0.0
    i1 = math.floor((psi1 - thi) / cell - 0.5)  # bearing interval holding psi1
    best_psi, best_f, best_s, best_s_at = psi1, -math.inf, -math.inf, math.nan
    for sign in (-1, 1):
        rot_s = sign * math.sin(cell)
        valley, valley_at = f1, math.nan  # valley_at: the table sample it is, if any
        prev, prev_psi = f1, psi1
        rising = False
        i = i1 + sign
        fresh = 0  # samples left before cos/sin are evaluated afresh
        wait = 0  # samples left before the block bound is tried again
        c = s = 0.0
        while abs(i - i1) <= nb // 2:
            mid = (i + 1.0) * cell + thi
            if fresh == 0:
                c, s, fresh = math.cos(mid - alpha), math.sin(mid - alpha), _ANCHOR
            if c <= cos_end:
                break
            if prev <= clear and wait <= 0:
                # block bound: can any of the next 8 intervals overlap at all? (if not, the saddle
                # between zones on either side is below the clearance, which is all that matters)
                dm = abs((mid - alpha + math.pi) % (2.0 * math.pi) - math.pi)
                j0 = i if sign > 0 else i - 7
                lo_g = (j0 + 0.5) * cell + thi
                if emag * math.cos(max(0.0, dm - 8.0 * cell)) - _node_min(sb, nb, j0, j0 + 8) - _node_min(
                        sj, nj, (lo_g - thj) * rj - 0.5, (lo_g + 8 * cell - thj) * rj - 0.5) <= clear:
                    if rising and prev > best_f:  # the peak was the last sample before the gap
                        best_psi, best_f, best_s, best_s_at = prev_psi, prev, valley, valley_at
                    if clear < valley:
                        valley, valley_at = clear, math.nan
                    prev, prev_psi = -math.inf, mid
                    rising = False
                    i += 8 * sign
                    fresh = 0
                    continue
                wait = 8
            f = _mid_overlap(sb, mb, nb, sj, mj, nj, i, emag * c, (mid - thj) * rj - 0.5)
            if f < prev:
                if rising and prev > best_f:  # passed a peak at the previous sample
                    best_psi, best_f, best_s, best_s_at = prev_psi, prev, valley, valley_at
                rising = False
                if f < valley:
                    valley, valley_at = f, mid
            elif f > prev:
                rising = True
            prev, prev_psi = f, mid
            c, s = c * rot_c - s * rot_s, s * rot_c + c * rot_s
            fresh -= 1
            wait -= 1
            i += sign
        if rising and prev > best_f:
            best_psi, best_f, best_s, best_s_at = prev_psi, prev, valley, valley_at
    if best_f <= floor:
        return psi1, -math.inf, -math.inf
    if not math.isnan(best_s_at):  # the saddle is a table sample: its value exactly
        best_s = overlap_at(sb, nb, sj, nj, emag, alpha, thi, thj, best_s_at)[0]
    best_f = overlap_at(sb, nb, sj, nj, emag, alpha, thi, thj, best_psi)[0]  # a table sample: exactly
    psi = _polish_peak(sb, nb, sj, nj, emag, alpha, thi, thj, best_psi, cell)
    f = overlap_at(sb, nb, sj, nj, emag, alpha, thi, thj, psi)[0]
    if f < best_f:
        psi, f = best_psi, best_f
    if abs((psi - psi1 + math.pi) % (2.0 * math.pi) - math.pi) < cell:
        return psi1, -math.inf, -math.inf  # climbed back into the top zone
    return psi, f, min(best_s, f)


@njit(cache=True)
def second_zone(sb, nb, sj, nj, emag, alpha, thi, thj, clear, psi1, f1):
    """:func:`search_second_zone` on bare depth arrays (builds the node-slope tables: O(n) per call)."""
    return search_second_zone(sb, node_slopes(sb, nb), nb, sj, node_slopes(sj, nj), nj, emag, alpha, thi, thj,
                              clear, psi1, f1)


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
