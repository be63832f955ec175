"""A bench's sensor-path calibration: fitted from sessions of a known state, used by later sessions.

``wearbench calibrate SESSION... --state NAME`` takes sessions of the bench in a state the lab knows
(right after assembly: new joints of known clearance), pools their cycles, and conditions the
sensor path's prior (``sensor_path.SensorPath.prior``) on how their features depart from that
state's ensemble (``sensor_path.calibrate_path``). The posterior (low-frequency gain and band gains
with their covariance) is stored as JSON under a key of the bench's physics, the accelerometer's
recorded calibration (name, sensitivity, range, axis, body and point in the session's
``calibration`` metadata), an optional mount label and the feature spec: later sessions of the same
bench, sensor and mount find it (:func:`find_calibration`) and identification and estimation use it
as their prior instead of the unmeasured mount's; their results name it.

Files live in ``$WEARBENCH_CALIBRATIONS`` (default ``~/.local/share/wearbench/calibrations``); an
existing calibration of the same key is a user file under the output-file policy: replaced only with
``force`` (``--force``), and only once the new one is complete.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from wearbench.bench.output_file import check_output, output_file
from wearbench.validation.inference import artefacts
from wearbench.validation.inference.sensor_path import SensorPath, calibrate_path, design_matrix
from wearbench.validation.measurement.features import CycleFeatures, FeatureSpec

__all__ = ["Calibration", "calibration_key", "calibration_path", "calibrations_dir", "check_calibration_output",
           "find_calibration", "fit_calibration", "load_calibration", "save_calibration", "sensor_record",
           "session_calibration"]

_SENSOR_FIELDS = ("name", "sensitivity", "range", "axis", "body", "point", "sample_rate")


def calibrations_dir() -> Path:
    return Path(os.environ.get("WEARBENCH_CALIBRATIONS",
                               Path.home() / ".local" / "share" / "wearbench" / "calibrations"))


def sensor_record(metadata: dict, bench=None) -> dict[str, str]:
    """The accelerometer's part of a session's ``calibration`` metadata record: the bench file's
    sensor as recorded. Its ``range`` is the bench file's (``bench``, the session's recorded bench):
    sessions recorded before the stream's range was recorded once (as ``acceleration.range``) also
    wrote it as ``accelerometer.range``, taken when there, so a key stays what it was."""
    cal = metadata.get("calibration", {})
    record = {f: cal.get(f"accelerometer.{f}", "") for f in _SENSOR_FIELDS}
    if "accelerometer.range" not in cal and bench is not None:
        try:
            record["range"] = repr(bench.sensor("accelerometer").range)
        except KeyError:
            pass
    return record


def calibration_key(bench, metadata: dict, spec: FeatureSpec, mount: str = "") -> str:
    """Content key of a calibration: bench physics, the accelerometer's recorded calibration, the
    mount label and the feature spec."""
    from wearbench.bench.content import bench_key

    content = {"bench": bench_key(bench), "sensor": sensor_record(metadata, bench), "mount": mount,
               "features": spec.to_dict()}
    return hashlib.sha256(json.dumps(content, sort_keys=True).encode()).hexdigest()


@dataclass(frozen=True)
class Calibration:
    """A fitted sensor path and where it came from."""

    key: str
    bench: str
    state: str
    sessions: tuple[str, ...]
    cycles: int
    mount: str
    path: SensorPath
    p_value: float  # consistency of the calibration sessions with the known state once the path is fitted
    created: str
    features: tuple[float, ...] = ()  # the sessions' mean cycle features (the spec's, all): ``relative_states.py``
    bench_key: str = ""  # the bench's physics and tolerances (``bench.content.bench_key``)
    doubts: tuple[str, ...] = ()  # why the sessions doubt the known state (stored with ``--force``)

    @property
    def about(self) -> artefacts.About:
        """Its artefact record: for its bench's sensor (and mount), at any speed."""
        return artefacts.About("calibration", self.key, self.bench, self.bench_key, float("nan"),
                               f"calibrated from {self.cycles} cycles of {self.state!r}"
                               + (f", mount {self.mount}" if self.mount else ""))

    def describe(self) -> str:
        g = self.path.gains_db()
        bands = ", ".join(f"{v:+.1f} dB" for k, v in g.items() if k != "gain")
        return (f"calibration {self.key[:12]} ({self.bench}{', mount ' + self.mount if self.mount else ''}: "
                f"{self.cycles} cycles of {self.state!r}, {self.created}; gain {g['gain']:.3f}, bands {bands})")

    def to_dict(self) -> dict:
        return {"key": self.key, "bench": self.bench, "state": self.state, "sessions": list(self.sessions),
                "cycles": self.cycles, "mount": self.mount, "path": self.path.to_dict(), "p_value": self.p_value,
                "created": self.created, "features": list(self.features), "bench_key": self.bench_key,
                "doubts": list(self.doubts)}

    @classmethod
    def from_dict(cls, d: dict) -> Calibration:
        return cls(d["key"], d["bench"], d["state"], tuple(d["sessions"]), int(d["cycles"]), d.get("mount", ""),
                   SensorPath.from_dict(d["path"]), float(d["p_value"]), d["created"],
                   tuple(float(v) for v in d.get("features", ())), d.get("bench_key", ""), tuple(d.get("doubts", ())))


def fit_calibration(features: Sequence[CycleFeatures], models_exact, state: str, *, key: str, bench: str,
                    labels: Sequence[str], mount: str = "", prior: SensorPath | None = None,
                    bench_key: str = "") -> Calibration:
    """Calibration from the cycle ``features`` of sessions of the known ``state``; ``models_exact``:
    ``StateModels`` fitted with the sensor path taken as exact (``IdentifyOptions(sensor_path="none")``)."""
    from scipy import stats

    if state not in models_exact.states:
        raise ValueError(f"calibrate: state {state!r} is not among the bench's states {list(models_exact.states)}")
    values = np.concatenate([f.values[:, models_exact.columns] for f in features])
    n = values.shape[0]
    if n < 1:
        raise ValueError("calibrate: the sessions hold no complete crank cycle")
    spec = models_exact.spec
    st = models_exact.stats[state]
    prior = prior or SensorPath.prior(spec)
    xbar = values.mean(axis=0)
    path = calibrate_path(xbar, st.mean, st.covariance(n), spec, prior,
                          source=f"calibration {key[:12]} ({n} cycles of {state!r})")
    resid = xbar - st.mean - design_matrix(spec, st.mean) @ path.theta_mean
    shape, scale = models_exact.null[state]
    p = float(stats.gamma.sf(float(resid @ np.linalg.solve(st.covariance(n), resid)), shape, scale=scale))
    full = np.full(spec.size, np.nan)
    full[models_exact.columns] = xbar
    return Calibration(key, bench, state, tuple(labels), n, mount, path, p,
                       time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime()) + " UTC",
                       tuple(float(v) for v in full) if np.isfinite(full).all() else (), bench_key)


def calibration_path(key: str, directory: str | Path | None = None) -> Path:
    """Where the calibration of ``key`` is stored: ``KEY.json`` under ``directory`` (default
    :func:`calibrations_dir`)."""
    return (Path(directory) if directory is not None else calibrations_dir()) / f"{key}.json"


def check_calibration_output(key: str, directory: str | Path | None = None, *, force: bool = False) -> Path:
    """Refuse (the output-file policy, ``bench.output_file``) to replace a stored calibration of
    ``key`` unless ``force``; the message names what the stored one holds. Returns its path."""
    path = calibration_path(key, directory)
    try:
        return check_output(path, force=force, option="calibration")
    except FileExistsError as exc:
        try:
            held = f"; it holds {load_calibration(path).describe()}"
        except (OSError, ValueError):
            held = ""
        raise FileExistsError(f"{exc}{held}; another --mount or --dir keeps both") from None


def save_calibration(cal: Calibration, directory: str | Path | None = None, *, force: bool = False) -> Path:
    """Write ``cal`` as ``KEY.json`` under ``directory`` (default :func:`calibrations_dir`): a user
    file under the output-file policy, so an existing calibration of the key is kept
    (FileExistsError) unless ``force``, and it is replaced only once the new one is complete."""
    path = check_calibration_output(cal.key, directory, force=force)
    with output_file(path, force=force, option="calibration") as tmp:
        artefacts.write_json(tmp, cal.about, cal.to_dict())
    return path


def load_calibration(path: str | Path) -> Calibration:
    """A calibration saved by :func:`save_calibration` (ArtefactError for a file that is not one)."""
    _, content = artefacts.read_json(path, "calibration")
    try:
        return Calibration.from_dict(content)
    except (KeyError, TypeError, ValueError) as exc:
        raise artefacts.ArtefactError(f"{path}: a calibration missing or damaging {exc}") from None


def find_calibration(key: str, directory: str | Path | None = None) -> Calibration | None:
    """The stored calibration of ``key`` (see :func:`calibration_key`), None when there is none."""
    path = calibration_path(key, directory)
    return load_calibration(path) if path.exists() else None


def session_calibration(session, spec: FeatureSpec, calibration: str | Path | None,
                        mount: str = "") -> Calibration | None:
    """The sensor-path calibration a session uses ("auto": the stored one of the session's
    bench, sensor and ``mount``, None when there is none; a path: that file; None: none)."""
    if calibration is None:
        return None
    if calibration != "auto":
        return load_calibration(calibration)
    if session.bench is None:
        return None
    return find_calibration(calibration_key(session.bench, session.metadata, spec, mount))
