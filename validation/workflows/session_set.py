"""A batch of recorded sessions, loaded once: grouped by bench and commanded speed, with the theory
and the sensor-path calibration each group uses.

Every workflow (identify, estimate, calibrate, track) starts from a :class:`SessionSet`: it loads the
sessions, gives each a label that tells it apart from the others (the shortest path that does, when
file names repeat), and groups them by bench file and commanded motor speed
(:meth:`SessionSet.groups`). For a group it finds the theory: ready-made ensembles or an estimator,
checked against the group's bench and speed before anything is built, else built on the compute
layer (:meth:`SessionSet.ensembles`, :meth:`SessionSet.estimator`); and each session's calibration
and cycle features, computed once (:meth:`SessionSet.calibration`, :meth:`SessionSet.features`).
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from wearbench.bench.content import file_digest
from wearbench.bench.load import load_states
from wearbench.bench.schema import Bench, WearState
from wearbench.compute.options import Compute
from wearbench.validation.estimation.estimate import (
    DesignRequest,
    Estimator,
    EstimatorDesign,
    build_estimator,
    load_estimator,
    resolve_design,
)
from wearbench.validation.inference.artefacts import ArtefactError
from wearbench.validation.inference.calibration import (
    Calibration,
    sensor_record,
    session_calibration,
)
from wearbench.validation.inference.ensemble import (
    Ensemble,
    EnsembleSettings,
    EnsembleSize,
    build_ensembles,
    check_ensembles_fit,
    load_ensembles,
    resolve_settings,
)
from wearbench.validation.measurement.features import CycleFeatures, FeatureSpec
from wearbench.validation.measurement.session import MeasuredSession, load_session

__all__ = ["SessionGroup", "SessionSet", "candidate_states", "distinct_labels"]

Sessions = Sequence[str | Path | MeasuredSession]


def distinct_labels(paths: Sequence[Path | None], labels: Sequence[str]) -> list[str]:
    """``labels``, each one shared by several sessions replaced by the shortest trailing part of its
    session's path that tells them apart (``dA/s`` and ``dB/s`` for two ``s.mcap``)."""
    out = list(labels)
    for label in {x for x in labels if labels.count(x) > 1}:
        idx = [i for i, x in enumerate(labels) if x == label and paths[i] is not None]
        parts = {i: Path(paths[i]).resolve().with_suffix("").parts for i in idx}
        tails = {i: label for i in idx}  # one file given twice: no path tells them apart (numbered below)
        for depth in range(2, max(len(p) for p in parts.values()) + 1):
            trial = {i: "/".join(p[-depth:]) for i, p in parts.items()}
            if len(set(trial.values())) == len(trial):
                tails = trial
                break
        suffix = {i: label.removeprefix(Path(paths[i]).stem) if tails[i] != label else "" for i in idx}
        for i in idx:
            out[i] = tails[i] + suffix[i]  # " (unfinished)" kept
    for label in {x for x in out if out.count(x) > 1}:  # one file given twice: numbered from the second
        for k, i in enumerate([i for i, x in enumerate(out) if x == label][1:], start=2):
            out[i] = f"{label} #{k}"
    return out


def candidate_states(bench: Bench, candidates: str | Path | Sequence[WearState] | None) -> tuple[WearState, ...]:
    """The candidate states: a ``[[state]]`` TOML file, ``WearState``s, or None for the bench's own."""
    if candidates is None:
        states = bench.states
    elif isinstance(candidates, (str, Path)):
        states = load_states(candidates, bench)
    else:
        states = tuple(candidates)
    if not states:
        raise ValueError(f"bench {bench.name!r} declares no [[state]] tables; give the candidate states "
                         "(--candidates STATES.toml)")
    return states


@dataclass
class SessionGroup:
    """Sessions of one bench file at one commanded motor speed (rad/s), and their places in the set."""

    bench: Bench | None
    speed: float
    indices: list[int]
    sessions: list[MeasuredSession]

    @property
    def first(self) -> MeasuredSession:
        return self.sessions[0]


class SessionSet:
    """Recorded sessions loaded once; see the module docstring.

    calibration: "auto" uses the stored calibration of each session's bench, sensor and ``mount`` when
    there is one; a calibration file uses that one (checked against each session's bench); None none.
    """

    def __init__(self, sessions: Sessions, *, calibration: str | Path | None = "auto", mount: str = ""):
        if not sessions:
            raise ValueError("no session given")
        loaded = [s if isinstance(s, MeasuredSession) else load_session(s) for s in sessions]
        labels = distinct_labels([s.path for s in loaded], [s.label for s in loaded])
        for s, label in zip(loaded, labels, strict=True):
            s.label = label
        self.sessions = loaded
        self.calibration_option, self.mount = calibration, mount
        self._calibrations: dict[tuple[int, FeatureSpec], Calibration | None] = {}
        self._features: dict[tuple[int, FeatureSpec], CycleFeatures] = {}

    @classmethod
    def of(cls, sessions: SessionSet | Sessions, **kwargs) -> SessionSet:
        """``sessions`` as a set (a set is used as it is)."""
        return sessions if isinstance(sessions, SessionSet) else cls(sessions, **kwargs)

    def __iter__(self) -> Iterator[MeasuredSession]:
        return iter(self.sessions)

    def __len__(self) -> int:
        return len(self.sessions)

    @property
    def labels(self) -> list[str]:
        return [s.label for s in self.sessions]

    def require_benches(self, needs: str) -> None:
        """Refuse (ValueError naming the session and why) a session without a usable bench file:
        ``needs`` says what needs one. Why is the session loader's own text where a bench file is
        recorded but does not load (worn-surface files it names missing beside it, say)."""
        for s in self.sessions:
            if s.bench is None:
                raise ValueError(f"session {s.label}: {s.bench_problem or 'no bench file recorded in it'}; {needs}")

    def refuse_duplicates(self, noun: str) -> None:
        """Refuse (ValueError) one recording given twice (the same file, or a copy of it, under any name):
        ``noun`` would count it as two sessions of the bench."""
        seen: dict[str, str] = {}
        for s in self.sessions:
            digest = (file_digest(s.path) if s.path is not None
                      else hashlib.sha256(s.acceleration[["time", "acc"]].to_numpy().tobytes()).hexdigest())
            if digest in seen:
                raise ValueError(f"session {s.label}: the same recording as {seen[digest]}; {noun} takes each "
                                 "session once")
            seen[digest] = s.label

    def groups(self) -> list[SessionGroup]:
        """The sessions grouped by bench file and commanded speed, in order of first appearance."""
        found: dict[tuple[str, float], SessionGroup] = {}
        for i, s in enumerate(self.sessions):
            speed = s.commanded_speed
            group = found.setdefault((s.bench.sha256 if s.bench else "", round(speed, 6)),
                                     SessionGroup(s.bench, speed, [], []))
            group.indices.append(i)
            group.sessions.append(s)
        return list(found.values())

    def one_bench(self, noun: str, *, sensor: bool = False) -> SessionGroup:
        """The one group of the set: every session of one bench file at one commanded speed (and, with
        ``sensor``, one recorded sensor calibration); else one ValueError naming the session that differs
        and what ``noun`` needs."""
        self.require_benches(f"{noun} needs one")
        first = self.sessions[0]
        for s in self.sessions[1:]:
            if s.bench.sha256 != first.bench.sha256:
                raise ValueError(f"session {s.label}: another bench file than {first.label}'s; {noun} takes the "
                                 "sessions of one bench")
            if sensor and sensor_record(s.metadata, s.bench) != sensor_record(first.metadata, first.bench):
                raise ValueError(f"session {s.label}: another sensor than {first.label}'s; {noun} takes the sessions "
                                 "of one bench and sensor")
        groups = self.groups()
        if len(groups) > 1:
            other = groups[1].first
            raise ValueError(f"session {other.label}: commanded at {other.commanded_speed:.6g} rad/s, "
                             f"{first.label} at {first.commanded_speed:.6g} rad/s; {noun} takes sessions at one speed")
        return groups[0]

    # ---- what each session uses ----------------------------------------------------------------

    def calibration(self, session: MeasuredSession, spec: FeatureSpec) -> Calibration | None:
        """The sensor-path calibration ``session`` uses with features of ``spec`` (computed once)."""
        tag = (id(session), spec)
        if tag not in self._calibrations:
            cal = session_calibration(session, spec, self.calibration_option, self.mount)
            if cal is not None and self.calibration_option != "auto":  # a file: is it this bench's?
                cal.about.check(self.calibration_option, bench=session.bench, session=session.label)
            self._calibrations[tag] = cal
        return self._calibrations[tag]

    def features(self, session: MeasuredSession, spec: FeatureSpec) -> CycleFeatures:
        """The cycle features of ``session`` in ``spec`` (computed once)."""
        tag = (id(session), spec)
        if tag not in self._features:
            self._features[tag] = session.features(spec)
        return self._features[tag]

    # ---- the theory each group uses --------------------------------------------------------------

    def ensembles(self, group: SessionGroup, *, candidates: str | Path | Sequence[WearState] | None = None,
                  settings: EnsembleSettings | EnsembleSize | None = None,
                  ensembles: Mapping[str, Ensemble] | str | Path | None = None,
                  compute: Compute | None = None, build: bool = True, cycles: int = 0) -> dict[str, Ensemble]:
        """The candidate states' ensembles for ``group``: ready-made ones (a mapping, or a file saved by
        ``wearbench ensemble``, refused where its bench, speed or candidates do not fit the group), else
        ``settings``' (an ``EnsembleSize`` or None resolved for the group's bench and speed,
        ``EnsembleSettings.for_bench``) built on the compute layer (``build=False``: checks only,
        returns {}); ``cycles``: the least settled cycles per realisation the caller needs (a file
        with fewer is refused)."""
        if isinstance(ensembles, (str, Path)):
            path = Path(ensembles)
            found = load_ensembles(path)
            bench = group.bench
            states = candidate_states(bench, candidates) if bench and (candidates or bench.states) else None
            check_ensembles_fit(path, found, bench=bench, states=states, speed=group.speed, session=group.first.label)
            held = min(e.features.shape[1] for e in found.values())
            if held < cycles:
                raise ArtefactError(f"{path}: {held} settled cycles per realisation; {cycles}-cycle windows need at "
                                    f"least {cycles} (wearbench ensemble --cycles {cycles + 1})")
            return found
        if ensembles is not None:
            return dict(ensembles)
        if group.bench is None:
            self.require_benches("candidate states need its bench")
        states = candidate_states(group.bench, candidates)
        settings = resolve_settings(settings, group.bench, group.speed)
        if not build:
            return {}
        return build_ensembles(group.bench, states, speed=group.speed, settings=settings,
                               compute=compute or Compute())

    def estimator(self, group: SessionGroup, *, design: EstimatorDesign | DesignRequest | None = None,
                  estimator: Estimator | str | Path | None = None, compute: Compute | None = None,
                  build: bool = True) -> Estimator | None:
        """The estimator for ``group``: a ready-made one (an ``Estimator`` or a file saved by ``wearbench
        estimator``), refused where it was built for another bench or speed; else ``design``'s (a
        ``DesignRequest`` or None resolved for the group's bench and speed, ``EstimatorDesign.for_bench``),
        the shipped one when its key matches, built on the compute layer otherwise (``build=False``:
        checks only, returns None)."""
        if isinstance(estimator, (str, Path)):
            estimator = load_estimator(estimator)
        if estimator is not None:
            if estimator.about is not None:
                where = estimator.path or f"estimator of {estimator.bench!r}"
                estimator.about.check(where, bench=group.bench, speed=group.speed, session=group.first.label)
            return estimator
        if group.bench is None:
            self.require_benches("the estimator needs its bench")
        design = resolve_design(design, group.bench, group.speed)
        if not build:
            return None
        return build_estimator(group.bench, design, speed=group.speed, compute=compute or Compute())

    def check_artefacts(self, *, ensembles=None, estimator=None, candidates=None, settings=None,
                        design=None, theory: tuple[str, ...] = (), cycles: int = 0) -> None:
        """Check every group's theory before any is built: ready-made ensembles or estimator against the
        group (one ArtefactError line), and the theory to build (``theory``: "ensembles", "estimator")
        resolved for each group's bench and speed, ``settings`` and ``design`` checked there (one
        ValueError line naming the option)."""
        for group in self.groups():
            if ensembles is not None or "ensembles" in theory:
                self.ensembles(group, candidates=candidates, ensembles=ensembles, settings=settings, build=False,
                               cycles=cycles)
            if estimator is not None or "estimator" in theory:
                self.estimator(group, estimator=estimator, design=design, build=False)

