"""The overlap of two worn surfaces at the bearing's interval midpoints, from per-surface tables.

Both contact-zone searches (``worn_contact``) compare the overlap
f(psi) = |e| cos(psi - alpha) - h_b(psi - th_b) - h_j(psi - th_j) at the midpoints of the bearing's
intervals (halfway between two region centres). :func:`surface_tables` is computed once per surface
(when the scene is packed); :func:`fill_midpoints` then writes f at every midpoint of the window
:func:`midpoint_window` (the directions |e| cos can still bring into contact) in one loop of a few
multiplications per sample, which both searches read: the bearing's midpoint depth is a table
row, |e| cos(psi - alpha) = e' . (cos, sin) of the midpoint in the bearing frame, and the journal,
when it has as many regions as the bearing, sits at the same fraction of its interval for every
midpoint. The samples equal :func:`overlap_at` to rounding; the searches evaluate every value they
return from the tables exactly. Imports numpy, numba, math and ``contact``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from wearbench.model.contact import (
    hermite,
    node_slopes,
    region_coordinate,
    region_interval,
    table_depth,
)

__all__ = ["TABLE_ROWS", "fill_midpoints", "midpoint_window", "surface_curvature", "surface_tables"]

TABLE_ROWS = 5  # depth, node slope, cos and sin of the midpoint angle, midpoint depth; each twice over
_MARGIN = 10  # intervals of the window beyond the reach of |e| cos


@njit(cache=True)
def surface_tables(depths: np.ndarray, n: int) -> np.ndarray:
    """(TABLE_ROWS, 2 n) tables of a surface of ``n`` regions: depths, PCHIP node slopes
    (``contact.node_slopes``, m per region), cos and sin of the body-frame angle 2 pi (k + 1) / n of
    the midpoint after centre k, and the depth there, each repeated once so that a window of up to
    n midpoints reads them without wrapping."""
    out = np.empty((TABLE_ROWS, 2 * n))
    slopes = node_slopes(depths, n)
    cell = 2.0 * math.pi / n
    for k in range(n):
        ang = (k + 1) * cell
        k1 = k + 1 if k + 1 < n else 0
        mid = hermite(depths[k], slopes[k], depths[k1], slopes[k1], 0.5)
        for rep in (k, k + n):
            out[0, rep] = depths[k]
            out[1, rep] = slopes[k]
            out[2, rep] = math.cos(ang)
            out[3, rep] = math.sin(ang)
            out[4, rep] = mid
    return out


@njit(cache=True)
def surface_curvature(table: np.ndarray, n: int) -> float:
    """The largest |h''| (m/rad^2) of a surface's PCHIP, from its :func:`surface_tables`: h'' is
    linear on each interval, so it is largest at an end of one."""
    top = 0.0
    for k in range(n):
        dy = table[0, k] - table[0, k + 1]
        m0, m1 = table[1, k], table[1, k + 1]
        top = max(top, abs(6.0 * dy + 4.0 * m0 + 2.0 * m1), abs(6.0 * dy + 2.0 * m0 + 4.0 * m1))
    scale = n / (2.0 * math.pi)
    return top * scale * scale


@njit(cache=True)
def midpoint_window(nb: int, emag: float, alpha: float, thi: float, clear: float) -> tuple[int, int]:
    """(i0, m): the bearing intervals i0 .. i0 + m - 1 around the one holding ``alpha``, all whose
    midpoints lie within min(pi/2, acos(clear/|e|)) + 10 intervals of it, beyond which the overlap
    cannot exceed the clearance (m <= nb: the whole circle for a coarse surface)."""
    cell = 2.0 * math.pi / nb
    half = min(0.5 * math.pi, math.acos(min(1.0, clear / emag))) + _MARGIN * cell
    ia = math.floor((alpha - thi) / cell - 0.5)
    h = math.ceil(half / cell) + 1
    if 2 * h + 1 >= nb:
        return ia - nb // 2, nb
    return ia - h, 2 * h + 1


@njit(cache=True)
def fill_midpoints(tb, tj, nb, nj, emag, alpha, thi, thj, i0, m, buf):
    """buf[t] = the overlap (m) at the midpoint of bearing interval i0 + t, t < m (see the module
    docstring); ``tb``, ``tj``: :func:`surface_tables` of bearing and journal."""
    ex = emag * math.cos(alpha - thi)  # e in the bearing frame
    ey = emag * math.sin(alpha - thi)
    k0 = i0 % nb
    cell = 2.0 * math.pi / nb
    rj = nj / (2.0 * math.pi)
    # views starting at the window's first entries: indices from 0 up let LLVM vectorise the loops
    cb, sb, hb = tb[2, k0:k0 + m], tb[3, k0:k0 + m], tb[4, k0:k0 + m]
    if nj == nb:  # the same fraction of a journal interval at every midpoint
        j0, _, fr = region_interval(region_coordinate((i0 + 1.0) * cell + thi - thj, nj), nj)
        w0 = hermite(1.0, 0.0, 0.0, 0.0, fr)
        w1 = hermite(0.0, 1.0, 0.0, 0.0, fr)
        w2 = hermite(0.0, 0.0, 1.0, 0.0, fr)
        w3 = hermite(0.0, 0.0, 0.0, 1.0, fr)
        yj, mj = tj[0, j0:j0 + m + 1], tj[1, j0:j0 + m + 1]
        for t in range(m):
            hj = w0 * yj[t] + w1 * mj[t] + w2 * yj[t + 1] + w3 * mj[t + 1]
            buf[t] = ex * cb[t] + ey * sb[t] - hb[t] - hj
    else:
        for t in range(m):
            xj = ((i0 + t + 1.0) * cell + thi - thj) * rj - 0.5
            buf[t] = ex * cb[t] + ey * sb[t] - hb[t] - table_depth(tj[0], tj[1], nj, xj)
