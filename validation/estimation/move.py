"""The benches' move from new to worn beyond an estimator's own mean change, measured on simulated
lives of known truth, and stored beside the estimator it was measured against.

``track`` on two or three sessions (new and one or two worn) reads the wear coefficient off the change
from new alone, and there the estimator's error *of that change* decides it: the design's mean change
is a mean over its M benches, so its error is shared by every bench the estimator judges
(``track.py``). :func:`life_move` measures it on lives whose truth is known; ``track_features(move=)``
moves the worn sessions' expected means by it and adds its standard error to the drift. The same lives
measure the rate at which the features change along a life against clearance (:class:`Rate`,
``track.life_rate``), stored with the move and marginalised by ``track``.

Stored as a sidecar ``NAME.move.npz`` beside the estimator ``NAME.npz`` (:func:`move_path`), not inside
it: the estimator file stays byte for byte what was built and checked (its key and the shipped
checks are untouched, and git keeps one copy of it), the move is measured later (hours of simulated
lives) and can be measured again without rewriting the estimator, and a rebuilt estimator cannot carry
a stale move inside it. The file holds the estimator's content key (``estimator``): a move is used only
with that estimator and refused with any other.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from wearbench.validation.estimation.estimate import Estimator, EstimatorModel
from wearbench.validation.inference import artefacts
from wearbench.validation.inference.statistics import shrunk_covariance

__all__ = ["Move", "Rate", "life_move", "load_move", "move_path", "save_move", "stored_move"]



@dataclass(frozen=True)
class Rate:
    """The rate at which benches' features change along their lives about the estimator's, against the
    initial clearance: lognormal with log-mean ``mean`` and sd ``spread`` at the clearance knots
    ``clearances`` (m), linear between them and held beyond (where no life measured it). Measured on
    the move's lives (``track.life_rate``); ``track`` marginalises it."""

    clearances: tuple[float, ...]
    mean: tuple[float, ...]
    spread: tuple[float, ...]

    def __post_init__(self):
        c, m, s = (np.asarray(v, float) for v in (self.clearances, self.mean, self.spread))
        if c.ndim != 1 or c.size < 1 or m.shape != c.shape or s.shape != c.shape or np.any(np.diff(c) <= 0) \
                or np.any(s < 0) or np.any(s >= 1) or not np.all(np.isfinite(m)):
            raise ValueError(f"rate: clearances {c.tolist()}, mean {m.tolist()}, spread {s.tolist()}: expected "
                             "increasing clearance knots with a finite log-mean and a lognormal sd in [0, 1) at each")

    def at(self, clearance: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """(log-mean, sd) of the rate at ``clearance`` (m)."""
        c = np.asarray(clearance, float)
        return np.interp(c, self.clearances, self.mean), np.interp(c, self.clearances, self.spread)

    def describe(self) -> str:
        return "features' rate along a life " + ", ".join(
            f"{np.exp(m):.2f}x (log sd {s:.2f}) at {c * 1e3:.3f} mm" for c, m, s in
            zip(self.clearances, self.mean, self.spread, strict=True)) + ", linear between, held beyond"


@dataclass(frozen=True)
class Move:
    """The mean (p,) of benches' move from new to worn beyond the estimator's mean change, the
    covariance (p, p) of that mean, the key of the estimator it was measured against, and what it was
    measured on (``about``: lives, sensor paths, seeds, factor, sessions, cycles per session)."""

    mean: np.ndarray
    covariance: np.ndarray
    estimator: str
    rows: np.ndarray  # (lives, p): each life's move, the measurement itself
    about: Mapping = field(default_factory=dict)
    path: str = ""  # the file it was read from ("" when measured in this process)
    rate: Rate | None = None  # the features' rate along the lives against clearance (None: not measured)

    def describe(self) -> str:
        """One line: what the move was measured on."""
        a = self.about
        paths = " and ".join(a.get("sensor_paths", [])) or "unstated sensor paths"
        seeds = a.get("seeds", [])
        seed_text = f"seeds {min(seeds)}-{max(seeds)}" if seeds else "unstated seeds"
        factor = a.get("factor")
        sessions = "/".join(f"{n / 1e3:.0f}k" for n in a.get("sessions", []))
        benches = a.get("benches", self.rows.shape[0])
        lives = f"{self.rows.shape[0]} simulated lives" + (f" of {benches} benches" if benches != self.rows.shape[0]
                                                            else "")
        return (f"measured on {lives} ({paths}; {seed_text}; wear factor "
                f"{factor if factor is not None else '?'} x the file's; sessions at {sessions or '?'} cycles run, "
                f"{a.get('cycles', '?')} cycles each)" + (f"; {self.rate.describe()}" if self.rate else "")
                + (f", {self.path}" if self.path else ""))

    def to_dict(self) -> dict:
        """What a result records of the move used (not its numbers)."""
        return {"file": self.path, "estimator": self.estimator, "lives": int(self.rows.shape[0]), **dict(self.about),
                "described": self.describe(), "rate": None if self.rate is None else {
                    "clearances": list(self.rate.clearances), "mean": list(self.rate.mean),
                    "spread": list(self.rate.spread), "described": self.rate.describe()}}


def life_move(model: EstimatorModel, lives: Sequence[tuple[np.ndarray, Sequence[float], float, float]],
              about: Mapping | None = None, benches: Sequence | None = None) -> Move:
    """The move measured on lives whose truth is known: each ``(session means (S, p), cycles run (S,),
    initial clearance, wear factor)`` with a session at 0 cycles and at least one worn. Per life, the
    worn sessions' mean residual at the truth less the new session's; the mean over the lives, and its
    covariance the lives' shrunk covariance / their number. ``benches``: each life's bench (lives of one
    drawn bench seen through different sensor paths are not independent): the lives of a bench are
    averaged first, and the mean and its covariance taken over the benches. ``about``: what the lives
    are (see :class:`Move`)."""
    rows = []
    for xbars, runs, clearance, factor in lives:
        runs = np.asarray(runs, float)
        if not (runs == 0).any() or not (runs > 0).any():
            raise ValueError(f"life_move: cycles run {list(runs)}: expected a session at 0 and a worn one")
        r = np.asarray(xbars, float) - model.mean(np.full(runs.shape, clearance), factor * runs)
        rows.append(r[runs > 0].mean(axis=0) - r[runs == 0].mean(axis=0))
    rows = np.asarray(rows)
    ids = list(range(len(rows))) if benches is None else list(benches)
    if len(ids) != len(rows):
        raise ValueError(f"life_move: {len(ids)} benches for {len(rows)} lives: expected one per life")
    per = np.stack([rows[[i for i, b in enumerate(ids) if b == u]].mean(axis=0) for u in dict.fromkeys(ids)])
    if per.shape[0] < 3:
        raise ValueError(f"life_move: {per.shape[0]} lives (benches): at least three are needed (the mean's "
                         "covariance is their spread)")
    return Move(per.mean(axis=0), shrunk_covariance(per) / per.shape[0], model.estimator.key, rows,
                {"bench": model.estimator.bench, **dict(about or {}), "benches": int(per.shape[0])})


def move_path(estimator_path: str | Path) -> Path:
    """Where the move of the estimator saved at ``estimator_path`` lives: ``NAME.move.npz`` beside ``NAME.npz``."""
    p = Path(estimator_path)
    return p.with_name(f"{p.name.removesuffix('.npz')}.move.npz")


def save_move(move: Move, path: str | Path) -> Path:
    """Write ``move`` as an artefact keyed by the estimator it was measured against."""
    paths = ", ".join(move.about.get("sensor_paths", [])) or "unstated"
    record = artefacts.About("move", move.estimator, str(move.about.get("bench", "")), "", float("nan"),
                             f"the lives' {paths}")
    rate = {} if move.rate is None else {"rate": np.array([move.rate.clearances, move.rate.mean, move.rate.spread])}
    return artefacts.write(path, record, {"mean": move.mean, "covariance": move.covariance, "rows": move.rows,
                                          "lives": np.array(json.dumps(dict(move.about))), **rate})


def load_move(path: str | Path, estimator: Estimator | str) -> Move:
    """The move saved at ``path``, which must have been measured against ``estimator`` (or its key):
    a move of another estimator, or a file that is not a move, raises one ArtefactError naming the
    file, the field and its value."""
    path = Path(path)
    key = estimator if isinstance(estimator, str) else estimator.key
    about, data = artefacts.read(path, "move")
    if about.key != key:
        raise artefacts.ArtefactError(
            f"{path}: a move measured against another estimator (key {about.key[:12]}); expected this estimator's "
            f"key {key[:12]} (measure it again: 'wearbench estimator ... --lives N', or track without it: --no-move)")
    try:
        mean, cov, rows = data["mean"], data["covariance"], data["rows"]
        lives = json.loads(str(data["lives"]))
    except (KeyError, ValueError) as exc:
        raise artefacts.ArtefactError(f"{path}: a move missing or damaging {exc}") from None
    rate = data.get("rate")
    p = mean.shape[0]
    if mean.shape != (p,) or cov.shape != (p, p) or rows.ndim != 2 or rows.shape[1] != p:
        raise artefacts.ArtefactError(f"{path}: field 'covariance' shape {cov.shape}, 'mean' {mean.shape}, 'rows' "
                                      f"{rows.shape}: expected (p, p), (p,) and (lives, p)")
    if rate is not None:
        if rate.ndim != 2 or rate.shape[0] != 3:
            raise artefacts.ArtefactError(f"{path}: field 'rate' shape {rate.shape}: expected (3, knots): "
                                          "clearances, log-mean, sd")
        try:
            rate = Rate(*(tuple(float(v) for v in row) for row in rate))
        except ValueError as exc:
            raise artefacts.ArtefactError(f"{path}: field 'rate': {exc}") from None
    return Move(mean, cov, about.key, rows, lives, str(path), rate)


def stored_move(estimator: Estimator) -> Move | None:
    """The move stored beside the file ``estimator`` was loaded from, when there is one (checked
    against its key: :func:`load_move`); None for an estimator built in this process or without one."""
    if estimator.path is None or not move_path(estimator.path).is_file():
        return None
    return load_move(move_path(estimator.path), estimator)
