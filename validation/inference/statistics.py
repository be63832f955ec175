"""The statistics of a state's cycle features, learnt from a theory ensemble, and how likely a
measured session's cycles are under them.

An ensemble of a state holds ``M`` realisations (benches drawn within their tolerances, random
start states) of ``C`` settled cycles each, every cycle a feature vector ``x`` (see
``features.py``). Cycles of one realisation share its bench; cycles of a measured session share
the real bench. So the model is hierarchical: ``x = mu + b + w``, with ``b ~ N(0, Sb)`` the
realisation's offset (bench against file) and ``w ~ N(0, Sw)`` the cycle's own (chaotic) part.
The mean of ``n`` cycles of one bench is then ``N(mu, Sb + Sw / n)``; the ensemble mean adds
``(Sb + Sw / C) / M``. ``Sw`` is the pooled within-realisation covariance, ``Sb`` the covariance
of the realisation means less ``Sw / C`` (clipped to positive semi-definite). Both are shrunk
towards their diagonals (Schäfer & Strimmer 2005, target "D", analytic intensity), because the
ensemble has fewer realisations than features. ``floor`` adds a per-feature variance for what
no ensemble holds: the sensor chain and the model's own error. ``nuisance`` (p, r) adds the
low-rank covariance ``F F^T`` of nuisance parameters marginalised analytically (an unknown sensor
path, ``sensor_path.py``): every distance and likelihood goes through :meth:`covariance`.

Pure numpy/scipy; imports nothing from wearbench but the feature spec.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from scipy import linalg

__all__ = ["StateStatistics", "shrunk_covariance"]


def shrunk_covariance(x: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """Covariance of the rows of ``x`` (n, p) shrunk towards its diagonal.

    Schäfer & Strimmer (2005), "A shrinkage approach to large-scale covariance matrix estimation",
    Stat. Appl. Genet. Mol. Biol. 4(1), target D: the correlations are shrunk towards 0 with the
    intensity lambda = sum Var(r_ij) / sum r_ij^2 (i != j), clipped to [0, 1].

    ``weights`` (n,), non-negative: the rows' weights (reliability weights: the moments are the
    weighted ones with the unbiased correction ``1 - sum a^2`` of the normalised weights ``a``, and
    the intensity's ``n`` is their effective number ``1 / sum a^2``); None: equal weights.
    """
    x = np.asarray(x, dtype=float)
    n, p = x.shape
    a = np.full(n, 1.0 / n) if weights is None else np.asarray(weights, dtype=float) / np.sum(weights)
    n_eff = 1.0 / float(np.sum(a * a))
    if n < 3 or not n_eff >= 3 - 1e-9 or (a < 0).any():
        raise ValueError(f"covariance: needs at least 3 samples (effective, non-negative weights), got {n} "
                         f"rows of effective number {n_eff:.3g}")
    if weights is None:
        xc = x - x.mean(axis=0)
        sd = xc.std(axis=0, ddof=1)
    else:
        xc = x - a @ x
        sd = np.sqrt(a @ (xc * xc) / (1.0 - 1.0 / n_eff))
    sd_safe = np.where(sd > 0, sd, 1.0)
    z = xc / sd_safe
    # w_k = z_k z_k^T: its weighted mean and spread as matrix products, sum a_k (w_k - wbar)^2 =
    # sum a_k w_k^2 - wbar^2 (sum a_k = 1), without the (n, p, p) products themselves
    z2 = z * z
    wbar = (z.T * a) @ z
    spread = np.clip((z2.T * a) @ z2 - wbar * wbar, 0.0, None)
    ne = float(n) if weights is None else n_eff
    r = wbar * ne / (ne - 1)
    var_r = ne ** 2 / (ne - 1) ** 3 * spread
    off = ~np.eye(p, dtype=bool)
    denom = float((r[off] ** 2).sum())
    lam = 1.0 if denom == 0 else float(np.clip(var_r[off].sum() / denom, 0.0, 1.0))
    rs = r * (1.0 - lam)
    np.fill_diagonal(rs, 1.0)
    return rs * np.outer(sd, sd)


def nearest_psd(a: np.ndarray) -> np.ndarray:
    a = 0.5 * (a + a.T)
    vals, vecs = np.linalg.eigh(a)
    return (vecs * np.clip(vals, 0.0, None)) @ vecs.T


@dataclass(frozen=True)
class StateStatistics:
    """Mean and covariances of a state's cycle features (see the module docstring)."""

    mean: np.ndarray  # (p,)
    within: np.ndarray  # Sw (p, p)
    between: np.ndarray  # Sb (p, p)
    floor: np.ndarray  # (p,) variance added for what the ensemble does not hold
    realisations: int  # M
    cycles: int  # C, cycles per realisation
    nuisance: np.ndarray | None = None  # (p, r): covariance F F^T of marginalised nuisance parameters
    _factors: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    @classmethod
    def fit(cls, values: np.ndarray, floor: np.ndarray) -> StateStatistics:
        """From an ensemble's features ``values`` (M realisations, C cycles, p features)."""
        values = np.asarray(values, dtype=float)
        if values.ndim != 3 or values.shape[0] < 3 or values.shape[1] < 2:
            raise ValueError(f"state statistics: expected (realisations >= 3, cycles >= 2, features), "
                             f"got {values.shape}")
        m, c, p = values.shape
        means = values.mean(axis=1)
        within = shrunk_covariance((values - means[:, None, :]).reshape(-1, p)) * (m * c - 1) / (m * (c - 1))
        between = nearest_psd(shrunk_covariance(means) - within / c)
        return cls(means.mean(axis=0), within, between, np.asarray(floor, dtype=float), m, c)

    @staticmethod
    def pooled(states: Sequence[StateStatistics]) -> list[StateStatistics]:
        """The ``states`` with one within- and one between-covariance, the mean of theirs.

        The states of one bench share its tolerances and its sensor, so the spread that the
        tolerances and the chaos give the features is estimated from all ensembles together (as
        linear discriminant analysis pools the class covariances): four times the realisations of
        one ensemble, where 72 features outnumber one ensemble's 32. Each state keeps its mean."""
        within = np.mean([s.within for s in states], axis=0)
        between = np.mean([s.between for s in states], axis=0)
        return [replace(s, within=within, between=between) for s in states]

    def with_nuisance(self, shift: np.ndarray, factor: np.ndarray) -> StateStatistics:
        """These statistics with nuisance parameters of Gaussian prior marginalised: the mean moves by
        ``shift`` (their prior mean's effect), the covariance gains ``factor factor^T``."""
        return replace(self, mean=self.mean + shift, nuisance=np.asarray(factor, dtype=float))

    def covariance(self, n: float, *, nuisance: bool = True) -> np.ndarray:
        """Covariance of the mean of ``n`` cycles of one bench about this ensemble's mean
        (``nuisance`` False: without the marginalised nuisance parameters)."""
        ens = (self.between + self.within / self.cycles) / self.realisations
        cov = self.between + self.within / n + ens + np.diag(self.floor)
        if nuisance and self.nuisance is not None:
            cov = cov + self.nuisance @ self.nuisance.T
        return cov

    def _factor(self, n: float) -> tuple[np.ndarray, float]:
        """Cholesky factor of ``covariance(n)`` and its log determinant, kept per ``n``."""
        if n not in self._factors:
            chol = linalg.cholesky(self.covariance(n), lower=True)
            self._factors[n] = (chol, 2.0 * float(np.log(np.diag(chol)).sum()))
        return self._factors[n]

    def whitener(self, n: float) -> np.ndarray:
        """Lower Cholesky factor ``L`` of ``covariance(n)``: ``L^-1 (x - mean)`` is white under the state."""
        return self._factor(n)[0]

    def distance2(self, xbar: np.ndarray, n: float) -> float:
        """Squared Mahalanobis distance of a session's mean features over ``n`` cycles."""
        z = linalg.solve_triangular(self.whitener(n), np.asarray(xbar, dtype=float) - self.mean, lower=True)
        return float(z @ z)

    def log_likelihood(self, xbar: np.ndarray, n: float) -> float:
        """Gaussian log density of a session's mean features over ``n`` cycles."""
        _, logdet = self._factor(n)
        return -0.5 * (self.distance2(xbar, n) + logdet + self.mean.size * np.log(2 * np.pi))
