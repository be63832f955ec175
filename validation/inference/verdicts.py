"""Identification verdicts scored against known truths, and how stable a number is over rebuilds.

What the identification benchmarks and tests measure sessions of known truth with: the Brier score,
top-1, named right and named wrong of a batch of identifications (:func:`verdict_scores`), and, for a
number that rebuilding the ensembles moves (a temperature, a score), its spread over rebuilds and the
smallest ensemble size from which that spread stays under a mark (:func:`spread`, :func:`stable_size`).
Imports numpy only.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

__all__ = ["spread", "stable_size", "verdict_scores"]


def spread(values: Sequence[float]) -> float:
    """Max - min of ``values`` (how far rebuilds move a number)."""
    return float(np.ptp(np.asarray(values, dtype=float)))


def stable_size(spreads: Mapping[int, float], mark: float = 0.1) -> int | None:
    """The smallest size from which on every measured size's spread is <= ``mark`` (None: not reached
    at the largest size; a size that meets it below a larger one that does not does not count)."""
    found = None
    for m in sorted(spreads, reverse=True):
        if not spreads[m] <= mark:
            break
        found = m
    return found


def verdict_scores(results: Sequence, truths: Sequence[str], names: Sequence[str]) -> dict[str, float]:
    """Brier score (sum over the candidates, mean over sessions), top-1, named right and named wrong of
    ``identify_features`` results against each session's true state."""
    rows = list(zip(results, truths, strict=True))
    return {"brier": float(np.mean([sum((r.posterior[s] - (s == t)) ** 2 for s in names) for r, t in rows])),
            "top1": float(np.mean([max(r.posterior, key=r.posterior.get) == t for r, t in rows])),
            "right": float(np.mean([r.verdict == t for r, t in rows])),
            "wrong": float(np.mean([r.verdict in names and r.verdict != t for r, t in rows]))}
