"""Dynamic time warping inside a Sakoe-Chiba band, compiled with numba.

Holds ``dtw_banded``: local cost ``(x_i - y_j)^2``, steps (i-1, j), (i, j-1), (i-1, j-1) each with
weight 1 (the step pattern of the ISO/TS 18571 reference implementation), path from (0, 0) to
(n-1, m-1) with ``|i - j| <= band``. Memory is O(n band) bytes (one direction byte per band cell)
and time O(n band), so a 50,000-sample window with a 500-sample band needs 50 MB and well under a
second, where a full matrix would need n m floats (20 GB). Ties prefer the diagonal, then (i-1, j)
(``ties="diagonal"``), or, as ISO/TS 18571's reference implementation does (checked against it in
tests/validation/test_metrics.py), (i, j-1), then (i-1, j), then the diagonal (``ties="standard"``).
Imports nothing from wearbench.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["dtw_banded"]

_DIAG, _UP, _LEFT = 0, 1, 2


@numba.njit(cache=True, nogil=True)
def _dtw_band(x: np.ndarray, y: np.ndarray, w: int, standard: bool):  # pragma: no cover - compiled
    n, m = x.size, y.size
    width = 2 * w + 1
    inf = np.inf
    prev = np.full(width, inf)
    cur = np.full(width, inf)
    steps = np.zeros((n, width), dtype=np.uint8)
    for i in range(n):
        for d in range(width):
            cur[d] = inf
        jlo = max(0, i - w)
        jhi = min(m - 1, i + w)
        for j in range(jlo, jhi + 1):
            d = j - i + w
            c = (x[i] - y[j]) ** 2
            if i == 0 and j == 0:
                cur[d] = c
                continue
            best = inf
            step = _DIAG
            if standard:  # the first minimum of (i, j-1), (i-1, j), (i-1, j-1)
                if j > 0 and d > 0:
                    best = cur[d - 1]
                    step = _LEFT
                if i > 0 and d + 1 < width and prev[d + 1] < best:
                    best = prev[d + 1]
                    step = _UP
                if i > 0 and j > 0 and prev[d] < best:
                    best = prev[d]
                    step = _DIAG
            else:
                if i > 0 and j > 0:
                    best = prev[d]  # (i-1, j-1): same offset in the previous row
                if i > 0 and d + 1 < width and prev[d + 1] < best:  # (i-1, j)
                    best = prev[d + 1]
                    step = _UP
                if j > 0 and d > 0 and cur[d - 1] < best:  # (i, j-1)
                    best = cur[d - 1]
                    step = _LEFT
            cur[d] = best + c
            steps[i, d] = step
        prev, cur = cur, prev
    cost = prev[m - 1 - (n - 1) + w]
    # back-track
    pi = np.empty(n + m, dtype=np.int64)
    pj = np.empty(n + m, dtype=np.int64)
    i, j, k = n - 1, m - 1, 0
    while True:
        pi[k] = i
        pj[k] = j
        k += 1
        if i == 0 and j == 0:
            break
        s = steps[i, j - i + w]
        if s == _DIAG:
            i -= 1
            j -= 1
        elif s == _UP:
            i -= 1
        else:
            j -= 1
    return cost, pi[:k][::-1].copy(), pj[:k][::-1].copy()


def dtw_banded(x: np.ndarray, y: np.ndarray, band: int, *, ties: str = "diagonal"
               ) -> tuple[float, np.ndarray, np.ndarray]:
    """DTW of ``x`` and ``y`` with ``|i - j| <= band``: (total cost, path indices into x, into y).
    ``ties``: "diagonal" or "standard" (see the module docstring).

    ``band >= |len(x) - len(y)|`` is required so that the end cell lies in the band.
    """
    x = np.ascontiguousarray(x, dtype=np.float64)
    y = np.ascontiguousarray(y, dtype=np.float64)
    if x.ndim != 1 or y.ndim != 1 or x.size == 0 or y.size == 0:
        raise ValueError(f"dtw: expected two non-empty 1-D signals, got shapes {x.shape} and {y.shape}")
    band = int(band)
    if band < abs(x.size - y.size):
        raise ValueError(f"dtw: band {band} must be at least the length difference {abs(x.size - y.size)}")
    band = min(band, max(x.size, y.size))
    if ties not in ("diagonal", "standard"):
        raise ValueError(f"dtw: ties = {ties!r}: expected 'diagonal' or 'standard'")
    cost, pi, pj = _dtw_band(x, y, band, ties == "standard")
    return float(cost), pi, pj
