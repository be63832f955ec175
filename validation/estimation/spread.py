"""The spread between wear realisations: how far one wear run of a bench is from another.

An estimator's design wears the nominal bench once per design clearance (the *reference* run) and
reads the features of every design point on that run's surfaces. A bench that wore on its own is
another wear realisation: the wear model's motion is chaotic, a bench built within the tolerances
wears its own way, and surfaces after the same cycles from the same clearance differ (the test
bed's shipped 200k-cycle journal of B holds 8.3 um where a rerun of today's model gives 6.4 um).
Reading a bench's features as if its surfaces were the reference run's puts its wear where the
reference run would have it and claims intervals too narrow for what the design knows.

The spread design (:class:`SpreadDesign`) wears ``runs`` more benches per design clearance, each
drawn from the bench file's ``[tolerances]`` with its own seed and random start
(``estimate.wear_trajectory``), and simulates ``realisations`` of each worn design point with the
design's first seeds, so that a run's difference from the reference run is paired, seed by seed.
:func:`measure_spread` turns those differences into the covariance between wear realisations of the
features' mean at each design cycles-run value (0 at 0 cycles: unworn surfaces are one surface):

- per worn design point and run, ``d`` = the run's mean features less the reference run's over the
  same seeds. The reference is itself one wear realisation, and the estimator's mean is the
  reference run's, so ``d d^T`` estimates what a new bench's mean differs from the estimator's by
  (twice the covariance about the expected surfaces), which is what the likelihood needs;
- less the paired realisations' own sampling error of ``d`` (the seeds' differences' covariance over
  their number);
- pooled over the design clearances and runs at each cycles-run value, shrunk towards its diagonal
  (``statistics.shrunk_covariance`` on the differences and their mirror images: a second moment about
  zero), negative eigenvalues clipped to zero (where the runs agree, what is left is a floor of about a
  fifth of the paired means' sampling error: wider, never narrower).

The likelihood adds it, linear in cycles run between the design's values, to the covariance of a
session's mean (``estimate.EstimatorModel``); the wear depth's interval draws on every run's depth.
Kept as a sidecar ``NAME.spread.npz`` beside the estimator ``NAME.npz`` (:func:`spread_path`), keyed by
the estimator and the spread design (:func:`spread_key`), so that the estimator file and the move
measured against it stay what they are.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from wearbench.validation.inference import artefacts
from wearbench.validation.inference.statistics import shrunk_covariance

__all__ = ["SPREAD_SEED", "SpreadDesign", "WearSpread", "load_spread", "measure_spread", "save_spread", "spread_key",
           "spread_path", "spread_seed"]

SPREAD_SEED = 30_000  # first seed of the spread's drawn benches: apart from the design's 1..M and the benchmarks'


@dataclass(frozen=True)
class SpreadDesign:
    """Wear runs per design clearance beside the reference run (``runs``; 0: no spread) and
    realisations of each of their worn design points (the design's first seeds)."""

    runs: int = 3
    realisations: int = 12

    def __post_init__(self) -> None:
        if int(self.runs) != self.runs or self.runs < 0:
            raise ValueError(f"--wear-runs {self.runs}: expected a whole number >= 0 (0: no spread between wear runs)")
        if self.runs and self.realisations < 3:
            raise ValueError(f"wear spread: {self.realisations} realisations per worn point: expected at least 3")

    def to_dict(self) -> dict:
        return asdict(self)


def spread_seed(clearance_index: int, run: int) -> int:
    """The seed of the bench drawn for wear run ``run`` (0-based) of design clearance ``clearance_index``."""
    return SPREAD_SEED + 100 * clearance_index + run


def spread_key(estimator_key: str, design: SpreadDesign) -> str:
    """Content address of a spread: its estimator's key (bench, design, speed, model source) and its design."""
    from wearbench.compute import task_key

    return task_key("wear-spread", estimator_key, design.to_dict())


@dataclass(frozen=True)
class WearSpread:
    """The covariance between wear realisations of the features' mean at each design cycles-run value
    (``covariance`` (cycles, p, p), 0 at 0 cycles), and the wear depth of every spread run (``depth``
    (runs, clearances, cycles), m), for the estimator keyed ``estimator``."""

    estimator: str
    key: str
    design: SpreadDesign
    cycles: tuple[float, ...]
    covariance: np.ndarray
    depth: np.ndarray
    path: Path | None = field(default=None, compare=False)

    def at(self, cycles_run: float) -> np.ndarray:
        """The covariance after ``cycles_run`` cycles: linear between the design's values, held beyond."""
        n = np.asarray(self.cycles, float)
        k = int(np.clip(np.searchsorted(n, cycles_run, side="right") - 1, 0, n.size - 2))
        w = float(np.clip((cycles_run - n[k]) / (n[k + 1] - n[k]), 0.0, 1.0))
        return (1 - w) * self.covariance[k] + w * self.covariance[k + 1]

    def describe(self) -> str:
        sd = np.sqrt(np.clip(np.diagonal(self.covariance[-1]), 0, None))
        return (f"{self.design.runs} drawn benches' wear runs per design clearance beside the reference run, "
                f"{self.design.realisations} realisations per worn point; wear depth after {self.cycles[-1]:,.0f} "
                f"cycles {self.depth[:, :, -1].min() * 1e6:.1f}-{self.depth[:, :, -1].max() * 1e6:.1f} um; median sd "
                f"between runs {float(np.median(sd)):.3g} (feature units)")


def measure_spread(reference: np.ndarray, runs: np.ndarray) -> np.ndarray:
    """The covariance between wear realisations (cycles, p, p) from the design's features
    ``reference`` (clearances, cycles, M, C, p) and the spread runs' ``runs`` (runs, clearances,
    cycles - 1, R, C, p) at the worn design points, realisation r of a run paired with the reference's
    r (R <= M; the module docstring gives the estimate)."""
    k, nc, nw, r, c = runs.shape[:5]
    if reference.shape[:2] != (nc, nw + 1) or reference.shape[2] < r or reference.shape[-1] != runs.shape[-1]:
        raise ValueError(f"wear spread: runs {runs.shape} do not pair with the design's features {reference.shape}")
    c = min(c, reference.shape[3])
    p = runs.shape[-1]
    out = np.zeros((nw + 1, p, p))
    for j in range(nw):
        rows, noise = [], np.zeros((p, p))
        for i in range(nc):
            ref = reference[i, j + 1, :r, :c].mean(axis=1)  # (R, p) per seed
            for q in range(k):
                e = runs[q, i, j, :, :c].mean(axis=1) - ref  # the seeds' paired differences
                rows.append(e.mean(axis=0))
                noise += np.cov(e, rowvar=False) / r
        d = np.asarray(rows)
        second = shrunk_covariance(np.concatenate([d, -d])) * (2 * len(d) - 1) / (2 * len(d))
        moment = second - np.diag(np.diag(noise) / len(d))
        w, v = np.linalg.eigh(moment)
        out[j + 1] = (v * np.clip(w, 0, None)) @ v.T
    return out


def spread_path(estimator_path: str | Path) -> Path:
    """Where the spread of the estimator saved at ``estimator_path`` lives: ``NAME.spread.npz`` beside ``NAME.npz``."""
    p = Path(estimator_path)
    return p.with_name(f"{p.name.removesuffix('.npz')}.spread.npz")


def save_spread(spread: WearSpread, path: str | Path, about: artefacts.About) -> Path:
    """Write ``spread`` with ``about`` (its estimator's record, made a spread's) as an artefact."""
    record = artefacts.About("wear-spread", spread.key, about.bench, about.bench_key, about.speed, about.sensor_path)
    return artefacts.write(path, record, {"covariance": spread.covariance, "depth": spread.depth,
                                          "cycles": np.asarray(spread.cycles, float),
                                          "estimator": np.array(spread.estimator),
                                          "design": np.array(json.dumps(spread.design.to_dict()))})


def load_spread(path: str | Path, estimator_key: str) -> WearSpread | None:
    """The spread saved at ``path`` when it was measured for the estimator keyed ``estimator_key``
    (None: another estimator's, stale); a file that is not a spread raises one ArtefactError naming it."""
    about, data = artefacts.read(path, "wear-spread")
    try:
        design = SpreadDesign(**json.loads(str(data["design"])))
        estimator = str(data["estimator"])
        cov, depth, cycles = data["covariance"], data["depth"], tuple(float(v) for v in data["cycles"])
    except (KeyError, ValueError, TypeError) as exc:
        raise artefacts.ArtefactError(f"{path}: a wear spread missing or damaging {exc}") from None
    if cov.ndim != 3 or cov.shape[0] != len(cycles) or cov.shape[1] != cov.shape[2] or depth.ndim != 3:
        raise artefacts.ArtefactError(f"{path}: field 'covariance' shape {cov.shape}, 'depth' {depth.shape}: expected "
                                      f"({len(cycles)}, p, p) and (runs, clearances, {len(cycles)})")
    if estimator != estimator_key or about.key != spread_key(estimator_key, design):
        return None
    return WearSpread(estimator, about.key, design, cycles, cov, depth, Path(path))
