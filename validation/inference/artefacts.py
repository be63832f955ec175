"""Keyed artefacts: theory built once, kept in a file that says what it is for.

Five kinds of result are built from a bench and kept: theory ensembles of candidate states
(``ensemble.py``), a clearance-and-wear estimator (``estimate.py``), the spread between wear
realisations and the benches' move, both measured against one estimator (``spread.py``, ``move.py``),
and a sensor-path calibration (``calibration.py``). Every such
file carries an :class:`About` record: its kind, its content key, the bench it was built for (name
and physics key), the commanded motor speed, the sensor path it assumes and the wearbench version.
This module owns what the five share:

- writing and reading that record with the arrays (:func:`write`, :func:`read`), and the one error
  vocabulary: no such file, a file that is no artefact, an artefact of another kind ("FILE is an
  ensembles file, not an estimator"), one built for another bench or speed (:meth:`About.check`);
- where precomputed artefacts of a shipped bench live (:func:`shipped_path`, in this package, which
  builds them) and the use of one when its key matches (:func:`shipped`);
- the rule for replacing a shipped artefact (:func:`ship_target`): only in a source checkout, never
  in an installed package, and an existing one only when asked.

The content keys themselves are :func:`wearbench.compute.task_key`'s. Imports the bench layer and numpy.
"""

from __future__ import annotations

import json
import zipfile
from dataclasses import asdict, dataclass
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import numpy as np
from wearbench.bench.output_file import check_output, save_npz

__all__ = [
    "KINDS",
    "SHIPPED",
    "About",
    "ArtefactError",
    "check_shipping",
    "read",
    "read_about",
    "read_json",
    "ship_target",
    "shipped",
    "shipped_path",
    "source_checkout",
    "write",
    "write_json",
]

# kind -> what a user calls a file of it, with the command that writes one
KINDS: dict[str, str] = {
    "ensembles": "an ensembles file ('wearbench ensemble')",
    "estimator": "an estimator ('wearbench estimator')",
    "move": "a move ('wearbench estimator --lives')",
    "calibration": "a calibration ('wearbench calibrate')",
    "wear-spread": "a wear spread ('wearbench estimator --wear-runs')",
}
FORMAT = 2  # version of the record; files without one come from wearbench before keyed records
SHIPPED = Path(__file__).with_name("shipped")  # precomputed artefacts of the shipped benches, by kind


class ArtefactError(ValueError):
    """A file that is not the artefact asked for, or one built for another bench or speed: one line
    naming the file and what differs."""


def _version() -> str:
    try:
        return version("wearbench")
    except PackageNotFoundError:
        return "unknown"


@dataclass(frozen=True)
class About:
    """What an artefact is and what it is for."""

    kind: str
    key: str  # content key (``compute.task_key`` of everything it was built from)
    bench: str  # the bench's name
    bench_key: str  # the bench's physics and tolerances (``bench.content.bench_key``); "" when not tied to one
    speed: float  # commanded motor speed (rad/s) it was built at; nan when not tied to one
    sensor_path: str  # the sensor path it assumes, in words
    wearbench: str = ""  # the version that wrote it
    format: int = FORMAT

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"artefact kind {self.kind!r}: expected one of {sorted(KINDS)}")
        if not self.wearbench:
            object.__setattr__(self, "wearbench", _version())

    @classmethod
    def of(cls, kind: str, key: str, bench, speed: float, sensor_path: str) -> About:
        """The record of an artefact of ``bench`` (a ``Bench``) built at ``speed`` (rad/s)."""
        from wearbench.bench.content import bench_key

        return cls(kind, key, bench.name, bench_key(bench), float(speed), sensor_path)

    def describe(self) -> str:
        speed = "" if not np.isfinite(self.speed) else f" at {self.speed:.6g} rad/s"
        return f"{self.kind} of bench {self.bench!r}{speed}, sensor path {self.sensor_path}"

    def check(self, path: str | Path, *, bench=None, speed: float | None = None, session: str = "") -> None:
        """Refuse (ArtefactError) an artefact built for another bench (physics or tolerances) than
        ``bench`` or another commanded ``speed`` (rad/s) than the ``session``'s; None: not checked."""
        whose = f"session {session}" if session else "the sessions"
        if bench is not None and self.bench_key:
            from wearbench.bench.content import bench_key

            if self.bench_key != bench_key(bench):
                same = "another version of " if self.bench == bench.name else ""
                raise ArtefactError(f"{path}: {_noun(self.kind)} built for bench {self.bench!r}; "
                                    f"{whose} recorded on {same}bench {bench.name!r} (other physics or tolerances)")
        if speed is not None and np.isfinite(self.speed) and not np.isclose(self.speed, speed, rtol=1e-6, atol=1e-9):
            raise ArtefactError(f"{path}: {_noun(self.kind)} built at {self.speed:.6g} rad/s; "
                                f"{whose} commanded at {speed:.6g} rad/s")

    def to_json(self) -> str:
        return json.dumps(asdict(self), sort_keys=True)

    @classmethod
    def from_json(cls, text: str, path: str | Path) -> About:
        try:
            data = json.loads(text)
            return cls(**{**data, "speed": float(data["speed"])})
        except (ValueError, TypeError, KeyError) as exc:
            raise ArtefactError(f"{path}: its 'about' record is damaged ({type(exc).__name__}: {exc})") from None


def write(path: str | Path, about: About, arrays: dict[str, np.ndarray]) -> Path:
    """Write an artefact: ``arrays`` and the ``about`` record in one compressed .npz at ``path``,
    through a temporary name (``bench.output_file.save_npz``). Whether ``path`` may be replaced is
    the caller's decision (the output-file policy)."""
    if "about" in arrays:
        raise ValueError("artefact arrays: 'about' is the record's own name")
    return save_npz(path, about=np.array(about.to_json()), **arrays)


def _noun(kind: str) -> str:
    return KINDS[kind].split(" (")[0]


def _wrong_kind(path: Path, found: str, kind: str) -> ArtefactError:
    return ArtefactError(f"{path} is {_noun(found)}, not {_noun(kind)}")


def _json_kind(path: Path) -> str | None:
    """The kind named by a JSON artefact's record (a calibration), None when ``path`` holds none."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        return data["about"]["kind"] if data["about"]["kind"] in KINDS else None
    except (OSError, UnicodeDecodeError, ValueError, TypeError, KeyError):
        return None


def _exists(path: Path, kind: str) -> None:
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file; expected {KINDS[kind]}")
    if not path.is_file():
        raise ArtefactError(f"{path}: is a folder; expected {KINDS[kind]}")


def _open(path: Path, kind: str) -> np.lib.npyio.NpzFile:
    _exists(path, kind)
    if not zipfile.is_zipfile(path):
        found = _json_kind(path)
        if found is not None:
            raise _wrong_kind(path, found, kind)
        raise ArtefactError(f"{path}: not {KINDS[kind]} (not an .npz archive)")
    try:
        return np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise ArtefactError(f"{path}: not {KINDS[kind]} ({type(exc).__name__}: {exc})") from None


def _about(data, path: Path, kind: str) -> About:
    if "about" not in data.files:
        legacy = ("an ensembles file" if "fit" in data.files else "an estimator" if "meta" in data.files
                  else "a move" if "estimator" in data.files else None)
        if legacy is None:
            raise ArtefactError(f"{path}: not {KINDS[kind]} (no 'about' record)")
        raise ArtefactError(f"{path}: {legacy} written by a wearbench before artefacts named what they are for; "
                            f"build it again ({KINDS[kind].split('(')[1].rstrip(')')})")
    about = About.from_json(str(data["about"]), path)
    if about.kind != kind:
        raise _wrong_kind(path, about.kind, kind)
    return about


def write_json(path: str | Path, about: About, content: dict) -> Path:
    """Write a JSON artefact (a calibration): ``content`` and the ``about`` record, to ``path`` as it
    is (the caller writes through the output-file policy's temporary name)."""
    Path(path).write_text(json.dumps({"about": json.loads(about.to_json()), **content}, indent=1), encoding="utf-8")
    return Path(path)


def read_json(path: str | Path, kind: str) -> tuple[About, dict]:
    """The record and the content of the JSON artefact of ``kind`` at ``path`` (ArtefactError for a
    file that is not one, naming the kind it is where it is another artefact)."""
    path = Path(path)
    _exists(path, kind)
    if zipfile.is_zipfile(path):
        try:
            with np.load(path, allow_pickle=False) as data:
                found = json.loads(str(data["about"]))["kind"]
        except (OSError, ValueError, KeyError, TypeError):
            found = None
        raise _wrong_kind(path, found, kind) if found in KINDS else ArtefactError(f"{path}: not {KINDS[kind]}")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        record = data.pop("about")
    except (UnicodeDecodeError, ValueError, TypeError, KeyError, AttributeError):
        raise ArtefactError(f"{path}: not {KINDS[kind]} (no JSON 'about' record)") from None
    about = About.from_json(json.dumps(record), path)
    if about.kind != kind:
        raise _wrong_kind(path, about.kind, kind)
    return about, data


def read_about(path: str | Path, kind: str) -> About:
    """The record of the artefact at ``path``, which must be of ``kind`` (ArtefactError otherwise)."""
    path = Path(path)
    with _open(path, kind) as data:
        return _about(data, path, kind)


def read(path: str | Path, kind: str, *, key: str | None = None) -> tuple[About, dict[str, np.ndarray]] | None:
    """The record and the arrays of the artefact of ``kind`` at ``path``; None when ``key`` is given
    and the artefact's differs (built from other content: stale). One ArtefactError line otherwise
    for a file that is not that artefact; OSError for a missing one."""
    path = Path(path)
    with _open(path, kind) as data:
        about = _about(data, path, kind)
        if key is not None and about.key != key:
            return None
        try:
            return about, {name: data[name] for name in data.files if name != "about"}
        except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
            raise ArtefactError(f"{path}: cut or damaged ({type(exc).__name__}: {exc})") from None


def shipped_path(kind: str, bench: str) -> Path:
    """Where a precomputed artefact of ``kind`` of the shipped bench named ``bench`` lives."""
    return SHIPPED / kind / f"{bench}.npz"


def shipped(kind: str, bench: str, key: str) -> tuple[About, dict[str, np.ndarray]] | None:
    """The shipped artefact of ``kind`` of ``bench`` when there is one and its key is ``key``."""
    path = shipped_path(kind, bench)
    return read(path, kind, key=key) if path.is_file() else None


def source_checkout() -> Path | None:
    """The root of the source checkout this package runs from (a folder holding ``pyproject.toml``
    beside the package's folders), None for an installed package."""
    root = Path(__file__).resolve().parents[2]
    return root if (root / "pyproject.toml").is_file() and (root / "validation").is_dir() else None


def check_shipping(path: Path) -> None:
    """Refuse (PermissionError) to write the shipped file ``path`` in an installed package: shipped files
    are the package's, and a reinstall would be the only way back."""
    if source_checkout() is None:
        raise PermissionError(f"--ship: wearbench is installed (not a source checkout), and its shipped files are "
                              f"the package's: {path} is not replaced; save it with --out instead")


def ship_target(kind: str, bench: str, *, force: bool = False) -> tuple[Path, About | None]:
    """The shipped location a maintainer's ``--ship`` writes to, and the record of the artefact it
    replaces (None: none there): refused in an installed package (shipped files are the package's:
    a reinstall is the only way back) and, where one exists, unless ``force``. Raises OSError
    subclasses with the one line the user sees."""
    path = shipped_path(kind, bench)
    check_shipping(path)
    try:
        check_output(path, force=force, option="--ship")
        return path, (read_about(path, kind) if path.exists() else None)
    except FileExistsError:
        held = read_about(path, kind)
        raise FileExistsError(f"--ship: {path} holds the shipped {held.describe()} (key {held.key[:12]}); pass "
                              "--force to replace it") from None
