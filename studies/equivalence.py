"""Are two versions of the model's statistics the same? The arithmetic of that gate.

``benchmarks/model/statistics_equivalence.py`` collects the cycle statistics of the test bed under two
versions of the model (or two solver settings) and asks whether each feature's distribution is the
same: a two-sample Kolmogorov-Smirnov test per feature, Holm-Bonferroni adjusted over the features
(:func:`compare`, :func:`holm`). Solver settings are named for its tables and files and read back
into ``simulate``'s keywords (:func:`label`, :func:`setting`, :func:`keywords`). Imports numpy and
scipy.
"""

from __future__ import annotations

import numpy as np
from scipy import stats

__all__ = ["compare", "holm", "keywords", "label", "setting"]


def holm(p: np.ndarray) -> np.ndarray:
    """Holm-Bonferroni adjusted p-values (monotone, capped at 1)."""
    p = np.asarray(p, dtype=float)
    order = np.argsort(p)
    adj = np.empty_like(p)
    running = 0.0
    for rank, i in enumerate(order):
        running = max(running, (p.size - rank) * p[i])
        adj[i] = min(1.0, running)
    return adj


def compare(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> list[tuple[str, float, float, float, float]]:
    """(feature, mean a, mean b, KS p, Holm-adjusted p) per feature."""
    keys = sorted(set(a) & set(b))
    p = np.array([stats.ks_2samp(a[k], b[k]).pvalue for k in keys])
    adj = holm(p)
    return [(k, float(np.mean(a[k])), float(np.mean(b[k])), float(p[i]), float(adj[i])) for i, k in enumerate(keys)]


def label(method: str, tolerances=None, scales=None) -> str:
    """A --dump file's name for its setting: the method, then "rtol R atol A" or "absolute scales P m, V m/s"."""
    if scales:
        return method + " absolute scales {:g} m, {:g} m/s".format(*scales)
    return method + (" rtol {:g} atol {:g}".format(*tolerances) if tolerances else "")


def setting(name: str) -> dict:
    """The options of a setting named by :func:`label` (scales: see :func:`keywords`)."""
    words = name.replace(",", "").split()
    if "scales" in words:
        i = words.index("scales")
        return {"method": words[0], "scales": (float(words[i + 1]), float(words[i + 3]))}
    if "rtol" in words:
        return {"method": words[0], "rtol": float(words[words.index("rtol") + 1]),
                "atol": float(words[words.index("atol") + 1])}
    return {"method": words[0]}


def keywords(options: dict) -> dict:
    """The ``simulate`` keywords of a :func:`setting`: its absolute scales (position m, velocity m/s) as the
    atol pair with rtol 0 (absolute error scales per kind of component, ``simulation.error_scales``)."""
    options = dict(options)
    scales = options.pop("scales", None)
    return options if scales is None else {**options, "rtol": 0.0, "atol": tuple(scales)}
