"""Worn surfaces of a clearance joint: wear depth per angular region on the bearing and the journal.

Holds the :class:`JointSurfaces` contract (see the paper, section 2.2: the worn profile is stored
as depths over equal angular regions fixed to each body), its ``.npz`` storage and the depth a
counter-body can reach. The interpolation between region centres is ``surface_tables``'. Imports
numpy and ``surface_tables`` (and, lazily, the bench dataclasses in :func:`surfaces_from_bench`); it
must not import the multibody model.

Worn geometry (contract): the bearing radius in direction phi (bearing frame) is
``R1 + bearing_depth(phi)``, the journal radius in direction phi (journal frame) is
``R2 - journal_depth(phi)``, with depths interpolated between region centres by a periodic PCHIP
(piecewise cubic Hermite, C1 and shape-preserving: the contact normal and penetration are
continuous, and no depth goes negative between two non-negative centres).
"""

from __future__ import annotations

import math
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from wearbench.model.surface_tables import depth_at

if TYPE_CHECKING:
    from wearbench.bench.schema import Bench

__all__ = ["JointSurfaces", "SurfaceError", "reachable_depth", "region_of", "surfaces_from_bench"]

_FORMAT = "wearbench.surfaces/1"


class SurfaceError(ValueError):
    """A worn-surface array or file is wrong: names the source, the field, the value and what was expected."""


def _check_depths(name: str, values: object, source: str) -> np.ndarray:
    try:
        arr = np.array(values, dtype=float)
    except (TypeError, ValueError):
        raise SurfaceError(f"{source}: {name} = {values!r}: expected an array of depths in m") from None
    if arr.ndim != 1 or arr.size < 3:
        raise SurfaceError(f"{source}: {name} has shape {arr.shape}: expected a 1-D array of at least "
                           "3 regions (depth per angular region, m)")
    bad = ~np.isfinite(arr)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise SurfaceError(f"{source}: {name}[{i}] = {arr[i]}: expected finite depths (m)")
    if (arr < 0).any():
        i = int(np.argmin(arr))
        raise SurfaceError(f"{source}: {name}[{i}] = {arr[i]:.3g} m: expected depths >= 0 "
                           "(wear only removes material)")
    return arr


@dataclass
class JointSurfaces:
    """Wear depth (m, >= 0) per angular region of one clearance joint's bearing and journal.

    Region ``i`` of an array of ``n`` covers the body-frame angles ``[2 pi i/n, 2 pi (i+1)/n)`` of
    the body it belongs to (bearing body or journal body); the depth is taken at the region centre.
    ``cycles`` is how many crank cycles of wear the depths represent; ``label`` names the state
    (e.g. "first wear").
    """

    bearing: np.ndarray
    journal: np.ndarray
    cycles: float = 0.0
    label: str = ""
    meta: dict[str, str] = field(default_factory=dict)  # free text notes (joint, bench, settings)

    def __post_init__(self) -> None:
        source = f"JointSurfaces({self.label or 'unlabelled'})"
        self.bearing = _check_depths("bearing", self.bearing, source)
        self.journal = _check_depths("journal", self.journal, source)
        if not (math.isfinite(self.cycles) and self.cycles >= 0):
            raise SurfaceError(f"{source}: cycles = {self.cycles!r}: expected a finite number >= 0")
        self.cycles = float(self.cycles)
        self.label = str(self.label)

    @classmethod
    def unworn(cls, regions: int = 1000, *, label: str = "unworn") -> JointSurfaces:
        """Both surfaces at zero depth with ``regions`` regions each."""
        return cls(np.zeros(regions), np.zeros(regions), 0.0, label)

    @property
    def max_depth(self) -> tuple[float, float]:
        """(bearing, journal) maximum depth, m."""
        return float(self.bearing.max()), float(self.journal.max())

    def bearing_depth(self, phi: float | np.ndarray) -> float | np.ndarray:
        """Bearing depth (m) in direction ``phi`` (rad, bearing frame), periodic PCHIP (C1)."""
        return depth_at(self.bearing, phi)

    def journal_depth(self, phi: float | np.ndarray) -> float | np.ndarray:
        """Journal depth (m) in direction ``phi`` (rad, journal frame), periodic PCHIP (C1)."""
        return depth_at(self.journal, phi)

    def scaled(self, factor: float, *, label: str | None = None) -> JointSurfaces:
        """Depths and cycles times ``factor`` (e.g. to extrapolate simulated cycles to a stage)."""
        return JointSurfaces(self.bearing * factor, self.journal * factor, self.cycles * factor,
                             self.label if label is None else label, dict(self.meta))

    def __add__(self, other: JointSurfaces) -> JointSurfaces:
        if self.bearing.shape != other.bearing.shape or self.journal.shape != other.journal.shape:
            raise SurfaceError(f"cannot add surfaces of {self.bearing.size}/{self.journal.size} regions "
                               f"and {other.bearing.size}/{other.journal.size} regions")
        return JointSurfaces(self.bearing + other.bearing, self.journal + other.journal,
                             self.cycles + other.cycles, other.label or self.label, dict(self.meta))

    def save(self, path: str | Path) -> Path:
        """Write to ``path`` (.npz; the suffix is added if missing). Returns the path written."""
        path = Path(path)
        if path.suffix != ".npz":
            path = path.with_name(path.name + ".npz")
        path.parent.mkdir(parents=True, exist_ok=True)
        meta = np.array([f"{k}={v}" for k, v in self.meta.items()], dtype=str)
        np.savez(path, format=np.array(_FORMAT), bearing=self.bearing, journal=self.journal,
                 cycles=np.array(self.cycles), label=np.array(self.label), meta=meta)
        return path

    @classmethod
    def load(cls, path: str | Path) -> JointSurfaces:
        """Read a file written by :meth:`save`; errors name the file and what is wrong."""
        path = Path(path)
        if path.is_file() and not zipfile.is_zipfile(path):
            raise SurfaceError(f"{path}: not a worn-surface .npz file (not an .npz archive)")
        try:
            with np.load(path, allow_pickle=False) as data:
                fields = {k: data[k] for k in data.files}
        except FileNotFoundError:
            raise OSError(f"{path}: worn-surface file does not exist") from None
        except (ValueError, OSError) as exc:
            raise SurfaceError(f"{path}: not a worn-surface .npz file ({exc})") from None
        fmt = str(fields.get("format", ""))
        if fmt != _FORMAT:
            raise SurfaceError(f"{path}: format = {fmt!r}: expected {_FORMAT!r} (written by JointSurfaces.save)")
        for key in ("bearing", "journal"):
            if key not in fields:
                raise SurfaceError(f"{path}: missing array {key!r}")
        meta = dict(s.split("=", 1) for s in fields.get("meta", np.array([], dtype=str)).tolist() if "=" in s)
        try:
            return cls(fields["bearing"], fields["journal"], float(fields.get("cycles", 0.0)),
                       str(fields.get("label", "")), meta)
        except SurfaceError as exc:
            raise SurfaceError(f"{path}: {exc}") from None


def region_of(phi: float | np.ndarray, n: int) -> int | np.ndarray:
    """Index of the region (of ``n``) holding body-frame angle ``phi`` (rad)."""
    idx = np.floor(np.mod(phi, 2 * np.pi) * (n / (2 * np.pi))).astype(int) % n
    return int(idx) if np.ndim(idx) == 0 else idx


def reachable_depth(depths: np.ndarray, clearance: float, oversample: int = 4) -> float:
    """Deepest point (m) of a worn surface that a circular counter-body can reach.

    A circular counter-body with radial clearance ``clearance`` (m) (R1 - R2 of the joint), pushed
    from the centre in direction a, first touches the worn surface (radius + depth h(phi), PCHIP
    profile) at the eccentricity |e|(a) = min_phi (clearance + h(phi)) / cos(phi - a) (small-clearance
    geometry, as in the contact kernel); it reaches |e|(a) - clearance into the wear. Returns the
    maximum over a. Equals the max depth for pits wider than the counter-body's relative curvature
    allows, and less for narrower ones. Evaluated on ``oversample`` points per region.
    """
    depths = np.asarray(depths, dtype=float)
    peak = float(depths.max()) if depths.size else 0.0
    if peak <= 0:
        return 0.0
    if not clearance > 0:
        raise ValueError(f"reachable depth: clearance = {clearance} m: expected > 0")
    m = depths.size * oversample
    phi = 2 * np.pi * (np.arange(m) + 0.5) / m
    h = depth_at(depths, phi)
    width = math.acos(min(1.0, clearance / (clearance + peak)))  # farther off, cos drops more than h can
    k = int(width * m / (2 * np.pi)) + 1
    offsets = np.arange(-k, k + 1)
    cosd = np.cos(offsets * 2 * np.pi / m)
    best = 0.0
    for lo in range(0, m, 512):  # blocks of directions a (bounded memory)
        a = np.arange(lo, min(m, lo + 512))
        reach = np.min((clearance + h[(a[:, None] + offsets[None, :]) % m]) / cosd[None, :], axis=1)
        best = max(best, float(reach.max()) - clearance)
    return best


def surfaces_from_bench(bench: Bench) -> dict[str, JointSurfaces]:
    """The worn surfaces a bench file names (``surfaces = "file.npz"`` in a ``[joint.clearance]``).

    Returns ``{joint name: JointSurfaces}`` for the joints that name one, ready for
    ``build_scene(bench, surfaces=...)``. Errors name the bench file and the joint.
    """
    out: dict[str, JointSurfaces] = {}
    for joint in bench.clearance_joints:
        path = joint.clearance.surfaces
        if path is None:
            continue
        try:
            out[joint.name] = JointSurfaces.load(path)
        except (SurfaceError, OSError) as exc:
            raise SurfaceError(f"{bench.path or bench.name}: joint {joint.name}.clearance.surfaces: {exc}") from None
    return out

