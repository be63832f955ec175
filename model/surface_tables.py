"""Periodic PCHIP surface tables of a worn joint: depth between region centres, and the overlap of
two surfaces at the bearing's interval midpoints.

A worn surface is a depth per equal angular region (``surfaces.JointSurfaces``); between region
centres the depth is a periodic PCHIP (piecewise cubic Hermite with Fritsch-Butland slopes; Fritsch &
Carlson, SIAM J. Numer. Anal. 17, 1980): C1 and shape-preserving, so the contact normal and the
penetration are continuous and no depth goes negative between two non-negative centres. This module
holds that interpolation once, in two forms: compiled scalar functions for the kernels (depth and its
derivatives from the depths, or from a table of node slopes computed once per surface) and
:func:`depth_at` on numpy arrays (profiles, reachable depth, reports).

Both contact-zone searches (``worn_contact``) compare the overlap
f(psi) = |e| cos(psi - alpha) - h_b(psi - th_b) - h_j(psi - th_j) at the midpoints of the bearing's
intervals (halfway between two region centres). :func:`surface_tables` is computed once per surface
(when the scene is packed); :func:`fill_midpoints` then writes f at every midpoint of the window
:func:`midpoint_window` (the directions |e| cos can still bring into contact) in one loop of a few
multiplications per sample, which both searches read: the bearing's midpoint depth is a table
row, |e| cos(psi - alpha) = e' . (cos, sin) of the midpoint in the bearing frame, and the journal,
when it has as many regions as the bearing, sits at the same fraction of its interval for every
midpoint. The samples equal ``worn_contact.overlap_at`` to rounding; the searches evaluate every
value they return from the tables exactly. Imports numpy, numba and math.

Units: SI (m, rad).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["TABLE_ROWS", "depth_at", "depth_eval", "fill_midpoints", "hermite", "midpoint_window", "node_slopes",
           "region_coordinate", "region_interval", "rewrap", "surface_curvature", "surface_tables", "table_depth",
           "table_depth_eval", "table_eval", "table_value"]

TABLE_ROWS = 5  # depth, node slope, cos and sin of the midpoint angle, midpoint depth; each twice over
_MARGIN = 10  # intervals of the window beyond the reach of |e| cos


@njit(cache=True, inline="always")
def _pchip_node_slope(d0: float, d1: float) -> float:
    """PCHIP slope (per region) at a node from its left and right differences (Fritsch-Butland
    harmonic mean for equal spacing; zero at a local extremum, so no overshoot)."""
    if d0 * d1 <= 0.0:
        return 0.0
    return 2.0 * d0 * d1 / (d0 + d1)


@njit(cache=True, inline="always")
def hermite(y0: float, m0: float, y1: float, m1: float, f: float) -> float:
    """Cubic Hermite value at fraction ``f`` of an interval from node values and slopes (per region)."""
    f2 = f * f
    f3 = f2 * f
    return (2.0 * f3 - 3.0 * f2 + 1.0) * y0 + (f3 - 2.0 * f2 + f) * m0 + (-2.0 * f3 + 3.0 * f2) * y1 \
        + (f3 - f2) * m1


@njit(cache=True)
def node_slopes(depths: np.ndarray, n: int) -> np.ndarray:
    """The PCHIP node slopes (m per region) of :func:`depth_eval` for the first ``n`` depths, a table
    computed once per surface so the contact search can sample depths without recomputing them."""
    out = np.zeros(depths.size)
    for i in range(n):
        out[i] = _pchip_node_slope(depths[i] - depths[i - 1 if i > 0 else n - 1],
                                   depths[i + 1 if i + 1 < n else 0] - depths[i])
    return out


@njit(cache=True, inline="always")
def region_interval(x: float, n: int) -> tuple[int, int, float]:
    """The interval (centres i0, i1) holding region coordinate ``x`` in [0, n] (centre i at x = i,
    periodic) and the fraction in it; wrap other coordinates first (``x - n floor(x / n)``)."""
    i = int(x)
    f = x - i
    i0 = i if i < n else i - n  # cheap periodic neighbours (no signed modulo: the hot path)
    i1 = i0 + 1 if i0 + 1 < n else 0
    return i0, i1, f


@njit(cache=True, inline="always")
def table_value(depths: np.ndarray, slopes: np.ndarray, n: int, x: float) -> float:
    """Depth (m) at region coordinate ``x`` in [0, n] (node i at x = i, periodic), the value of
    :func:`depth_eval` at phi = 2 pi (x + 0.5) / n, from the :func:`node_slopes` table."""
    i0, i1, f = region_interval(x, n)
    return hermite(depths[i0], slopes[i0], depths[i1], slopes[i1], f)


@njit(cache=True, inline="always")
def table_depth(depths: np.ndarray, slopes: np.ndarray, n: int, x: float) -> float:
    """:func:`table_value` at any region coordinate ``x`` (wrapped first)."""
    return table_value(depths, slopes, n, x - n * math.floor(x / n))


@njit(cache=True, inline="always")
def region_coordinate(phi: float, n: int) -> float:
    """The region coordinate in [0, n] of body-frame angle ``phi`` (rad; centre i at i)."""
    x = phi * (n / (2.0 * math.pi)) - 0.5
    return x - n * math.floor(x / n)


@njit(cache=True, inline="always")
def rewrap(x: float, n: int) -> float:
    """A region coordinate within n of [0, n] wrapped into [0, n] by one comparison (a coordinate
    stepped from a wrapped one: no division)."""
    if x >= n:
        return x - n
    return x + n if x < 0.0 else x


@njit(cache=True, inline="always")
def _locate(n: int, phi: float) -> tuple[int, int, float]:
    """The interval (centres i0, i1) holding body-frame angle ``phi`` and the fraction in it."""
    return region_interval(region_coordinate(phi, n), n)


@njit(cache=True, inline="always")
def _hermite_eval(y0: float, m0: float, y1: float, m1: float, f: float, n: int) -> tuple[float, float, float]:
    """Depth and its first and second derivatives in phi at fraction ``f`` of an interval."""
    f2 = f * f
    h = hermite(y0, m0, y1, m1, f)
    dh = (6.0 * f2 - 6.0 * f) * (y0 - y1) + (3.0 * f2 - 4.0 * f + 1.0) * m0 + (3.0 * f2 - 2.0 * f) * m1
    d2h = (12.0 * f - 6.0) * (y0 - y1) + (6.0 * f - 4.0) * m0 + (6.0 * f - 2.0) * m1
    scale = n / (2.0 * math.pi)
    return h, dh * scale, d2h * scale * scale


@njit(cache=True)
def depth_eval(depths: np.ndarray, n: int, phi: float) -> tuple[float, float, float]:
    """Wear depth (m) at body-frame angle ``phi`` (rad) and its first and second derivatives
    (m/rad, m/rad^2): periodic PCHIP through the centres of ``n`` equal regions (region i covers
    [2 pi i/n, 2 pi (i+1)/n), its centre holds ``depths[i]``).

    PCHIP (piecewise cubic Hermite with Fritsch-Carlson/Butland slopes; Fritsch & Carlson, SIAM J.
    Numer. Anal. 17, 1980) is C1, so the depth, the contact normal and the penetration are
    continuous; it is local (four values per interval, no coefficients to precompute) and
    shape-preserving (no negative depths, no new extrema at the edge of a pit, which a C2 spline
    would add). The second derivative is piecewise linear (used by the contact search only).
    """
    i0, i1, f = _locate(n, phi)
    im = i0 - 1 if i0 > 0 else n - 1
    i2 = i1 + 1 if i1 + 1 < n else 0
    y0 = depths[i0]
    y1 = depths[i1]
    d = y1 - y0
    m0 = _pchip_node_slope(y0 - depths[im], d)
    m1 = _pchip_node_slope(d, depths[i2] - y1)
    return _hermite_eval(y0, m0, y1, m1, f, n)


@njit(cache=True, inline="always")
def table_eval(depths: np.ndarray, slopes: np.ndarray, n: int, x: float) -> tuple[float, float, float]:
    """Depth (m) and its first and second derivatives in phi at region coordinate ``x`` in [0, n]
    (see :func:`table_value`)."""
    i0, i1, f = region_interval(x, n)
    return _hermite_eval(depths[i0], slopes[i0], depths[i1], slopes[i1], f, n)


@njit(cache=True, inline="always")
def table_depth_eval(depths: np.ndarray, slopes: np.ndarray, n: int, phi: float) -> tuple[float, float, float]:
    """:func:`depth_eval` (the same values) with the node slopes read from the :func:`node_slopes`
    table instead of computed."""
    return table_eval(depths, slopes, n, region_coordinate(phi, n))


def _pchip_slopes(depths: np.ndarray) -> np.ndarray:
    """Periodic PCHIP node slopes (m per region): harmonic mean of the neighbouring differences,
    zero at a local extremum (Fritsch-Butland; the rule of :func:`node_slopes`), on a numpy array."""
    d_right = np.roll(depths, -1) - depths
    d_left = depths - np.roll(depths, 1)
    prod = d_left * d_right
    with np.errstate(divide="ignore", invalid="ignore"):
        m = np.where(prod > 0, 2.0 * prod / np.where(prod > 0, d_left + d_right, 1.0), 0.0)
    return m


def depth_at(depths: np.ndarray, phi: float | np.ndarray) -> float | np.ndarray:
    """Depth (m) at angle ``phi`` (rad): periodic PCHIP (C1, shape-preserving) through the region
    centres, region ``i`` of ``n`` centred at ``2 pi (i + 0.5)/n``, on numpy arrays; the same curve
    the contact kernel evaluates (:func:`depth_eval`)."""
    n = depths.size
    x = np.mod(phi, 2 * np.pi) * (n / (2 * np.pi)) - 0.5
    i0 = np.floor(x).astype(int)
    f = x - i0
    m = _pchip_slopes(depths)
    y0, y1 = depths[i0 % n], depths[(i0 + 1) % n]
    m0, m1 = m[i0 % n], m[(i0 + 1) % n]
    f2, f3 = f * f, f * f * f
    out = (2 * f3 - 3 * f2 + 1) * y0 + (f3 - 2 * f2 + f) * m0 + (-2 * f3 + 3 * f2) * y1 + (f3 - f2) * m1
    return float(out) if np.ndim(out) == 0 else out


@njit(cache=True)
def surface_tables(depths: np.ndarray, n: int) -> np.ndarray:
    """(TABLE_ROWS, 2 n) tables of a surface of ``n`` regions: depths, PCHIP node slopes
    (:func:`node_slopes`, m per region), cos and sin of the body-frame angle 2 pi (k + 1) / n of
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
