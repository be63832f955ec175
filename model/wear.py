"""Archard wear of a revolute clearance joint: pure laws on arrays (paper section 2.2).

Holds the Hertz line-contact half-width, the contact pressure, the sliding distance per step and
the accumulation of a contact record (one row per accepted integrator step) into wear depths per
angular region of the bearing and the journal. Imports numpy, pandas, numba, the surfaces contract
and the depth law of ``contact``; it must not import the multibody model (the stage loop in
``wear_stages`` wires them).

Where the wear goes (``footprint``): ``"pressure"`` (default) spreads each step's Archard volume
over the contact arc in proportion to the local overlap of the two worn surfaces, the
elastic-foundation (Winkler) pressure p = k_f x overlap that Mukras et al. use to distribute the
load of a worn revolute joint (Mukras, Kim, Sawyer, Jackson, Bergquist, *Wear* 266 (2009) 822-831;
*J. Tribol.* 132 (2010) 021603; after Podra & Andersson, *Wear* 224 (1999) 13-21). A journal
bridging a pit loads both rims, so the rims wear and the pit widens instead of deepening to a
spike. ``"hertz"`` spreads it evenly over the Hertz width, ``"region"`` puts it in one region (the
paper's procedure).

Units: SI throughout (m, N, Pa, s, rad). Equation numbers (eq. 15-21) are the paper's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd
from numba import njit
from wearbench.model.contact import conformal_radius, effective_modulus
from wearbench.model.surface_tables import (
    node_slopes,
    region_coordinate,
    region_interval,
    rewrap,
    table_eval,
    table_value,
)
from wearbench.model.surfaces import JointSurfaces

__all__ = [
    "FOOTPRINTS",
    "SLIDING",
    "WearLaw",
    "accumulate_wear",
    "contact_pressure",
    "deposit_arcs",
    "hertz_half_width",
    "sliding_distance",
    "worn_volume",
]

SLIDING = ("rotation", "tangential")
FOOTPRINTS = ("pressure", "hertz", "region")


def hertz_half_width(fn: np.ndarray | float, r_eff: float, e_eff: float, length: float) -> np.ndarray | float:
    """Half-width b (m) of the Hertz line contact of two parallel cylinders.

    b = sqrt(4 F R* / (pi L E*)), F normal force (N, >= 0), R* effective radius (m), L axial
    length (m), E* contact modulus (Pa). Johnson, *Contact Mechanics* (1985), eq. 4.43
    (with P = F/L the load per unit length); also Flores et al., *Kinematics and Dynamics of
    Multibody Systems with Imperfect Joints* (2008), eq. 3.25.
    """
    return np.sqrt(4.0 * np.maximum(fn, 0.0) * r_eff / (math.pi * length * e_eff))


def contact_pressure(fn: np.ndarray | float, half_width: np.ndarray | float, length: float) -> np.ndarray | float:
    """Mean contact pressure P = F / A (Pa), A = 2 b L the Hertz contact area (paper eq. 16).

    Zero where the force or the width is zero.
    """
    fn = np.asarray(fn, dtype=float)
    area = 2.0 * np.asarray(half_width, dtype=float) * length
    with np.errstate(divide="ignore", invalid="ignore"):
        p = np.where(area > 0, fn / np.where(area > 0, area, 1.0), 0.0)
    return p if p.ndim else float(p)


def sliding_distance(dt: np.ndarray, omega_rel: np.ndarray, vt: np.ndarray, r1: float,
                     kind: str = "rotation") -> np.ndarray:
    """Relative sliding distance (m) per step.

    ``"rotation"`` (paper eq. 19-20): dS = R1 |omega_journal - omega_bearing| dt, the bearing
    radius times the relative rotation of the two bodies in the step. It ignores the motion of the
    contact point itself (the journal rolling round the bearing).
    ``"tangential"``: dS = |v_t| dt, the relative tangential velocity of the contact points; it
    includes that rolling motion and is the usual choice when the contact point moves.
    """
    if kind == "rotation":
        return r1 * np.abs(omega_rel) * dt
    if kind == "tangential":
        return np.abs(vt) * dt
    raise ValueError(f"sliding = {kind!r}: expected one of {list(SLIDING)}")


@dataclass(frozen=True)
class WearLaw:
    """Archard wear of one clearance joint (paper eq. 16-21), depth h = K_n P dS per step.

    coefficient: K_n = K_m / H (1/Pa); bearing_radius, journal_radius, axial_length (m);
    modulus: E* (Pa, see :func:`effective_modulus`); split: share of each depth increment on the
    bearing (0.5: equal depths on both surfaces as in the paper; their sum is K_n P dS, so the worn
    volume of the pair is the Archard volume K_n F S); sliding: see :func:`sliding_distance`;
    footprint: ``"pressure"`` spreads the Archard volume K_n F dS over the arc where the two worn
    surfaces overlap, in proportion to the overlap (elastic foundation, see the module docstring;
    volume-exact; needs the surfaces the record was simulated on), ``"hertz"`` spreads the depth
    evenly over the Hertz contact width 2b on each surface (volume-exact), ``"region"`` puts it all
    in the single region in contact (the paper's procedure; its worn volume is K_n F S times region
    width / 2b).
    The Hertz width uses the unworn radii (wear depths are microns against a clearance of tenths of
    a millimetre).
    """

    coefficient: float
    bearing_radius: float
    journal_radius: float
    axial_length: float
    modulus: float
    split: float = 0.5
    sliding: str = "rotation"
    footprint: str = "pressure"

    def __post_init__(self) -> None:
        if not self.coefficient >= 0:
            raise ValueError(f"wear coefficient = {self.coefficient}: expected >= 0 (1/Pa)")
        if not 0 <= self.split <= 1:
            raise ValueError(f"wear split = {self.split}: expected a share in [0, 1]")
        if self.sliding not in SLIDING:
            raise ValueError(f"wear sliding = {self.sliding!r}: expected one of {list(SLIDING)}")
        if self.footprint not in FOOTPRINTS:
            raise ValueError(f"wear footprint = {self.footprint!r}: expected one of {list(FOOTPRINTS)}")
        conformal_radius(self.bearing_radius, self.journal_radius)  # validates the radii

    @classmethod
    def from_bench(cls, bench, joint: str, **overrides) -> WearLaw:
        """The law for clearance joint ``joint`` of a :class:`~wearbench.bench.schema.Bench`."""
        c = bench.joint(joint).clearance
        if c is None:
            raise ValueError(f"{bench.name}: joint {joint} has no clearance, so no wear")
        bm, jm = c.bearing_material, c.journal_material
        kw = {"coefficient": bench.wear.coefficient, "bearing_radius": c.bearing_radius,
                  "journal_radius": c.journal_radius, "axial_length": c.axial_length,
                  "modulus": effective_modulus(bm.youngs_modulus, bm.poisson_ratio, jm.youngs_modulus,
                                            jm.poisson_ratio),
                  "split": bench.wear.split}
        kw.update(overrides)
        return cls(**kw)

    @property
    def r_eff(self) -> float:
        return conformal_radius(self.bearing_radius, self.journal_radius)

    def half_width(self, fn):
        """Hertz half-width b (m) for normal force ``fn`` (N)."""
        return hertz_half_width(fn, self.r_eff, self.modulus, self.axial_length)

    def pressure(self, fn):
        """Mean Hertz pressure P (Pa) for normal force ``fn`` (N)."""
        return contact_pressure(fn, self.half_width(fn), self.axial_length)

    def depth_increments(self, fn, dt, omega_rel, vt=None) -> np.ndarray:
        """Total depth increment h = K_n P dS (m) per step (paper eq. 18), before the split."""
        fn = np.asarray(fn, dtype=float)
        vt = np.zeros_like(fn) if vt is None else np.asarray(vt, dtype=float)
        ds = sliding_distance(np.asarray(dt, float), np.asarray(omega_rel, float), vt, self.bearing_radius,
                              self.sliding)
        return self.coefficient * np.where(fn > 0, self.pressure(fn), 0.0) * ds


def deposit_arcs(n: int, centre_regions: np.ndarray, half_regions: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """Spread ``depth`` (m) evenly over arcs [c - w, c + w] (region units, periodic over ``n``).

    Each region gets depth times the fraction of it the arc covers, so sum(result) * region width
    = sum(depth * 2 w) * region width: the deposited volume is exact. Vectorised with a
    difference array; ``w`` must be below n/2.
    """
    out = np.zeros(n)
    if depth.size == 0:
        return out
    a0 = np.mod(centre_regions - half_regions, n)
    a1 = a0 + 2 * half_regions  # in [0, 2n)
    i0 = np.floor(a0).astype(int)
    i1 = np.floor(a1).astype(int)
    ext = np.zeros(2 * n + 2)
    diff = np.zeros(2 * n + 3)
    same = i0 == i1
    np.add.at(ext, i0[same], depth[same] * (a1[same] - a0[same]))
    d = ~same
    np.add.at(ext, i0[d], depth[d] * (i0[d] + 1 - a0[d]))
    np.add.at(ext, i1[d], depth[d] * (a1[d] - i1[d]))
    np.add.at(diff, i0[d] + 1, depth[d])
    np.add.at(diff, i1[d], -depth[d])
    ext += np.cumsum(diff)[: 2 * n + 2]
    out += ext[:n] + ext[n: 2 * n]
    out[:2] += ext[2 * n: 2 * n + 2]
    return out


def _swept_deposit(n: int, start: np.ndarray, sweep: np.ndarray, half: np.ndarray,
                   depth: np.ndarray) -> np.ndarray:
    """Deposit ``depth`` (m) of footprints of half-width ``half`` that move by ``sweep`` from
    ``start`` during their step (region units): each step is cut into ceil(4 |sweep| / half) equal
    sub-steps (at most 256), each depositing its share over its own footprint, so a contact point
    that runs over several regions in one step wears all of them, not only where the step ends."""
    m = np.clip(np.ceil(4 * np.abs(sweep) / np.maximum(half, 1e-12)), 1, 256).astype(int)
    rows = np.repeat(np.arange(m.size), m)
    j = np.arange(rows.size) - np.repeat(np.cumsum(m) - m, m)
    centre = start[rows] + sweep[rows] * (j + 0.5) / m[rows]
    return deposit_arcs(n, np.mod(centre, n), half[rows], depth[rows] / m[rows])


@njit(cache=True)
def _overlap_deposit(sb, sj, clear, pen, phib, phij, vol_b, vol_j, dims, out_b, out_j):
    """Spread the worn volumes ``vol_b``, ``vol_j`` (m^3 per row) over each row's overlap arc, on a joint of
    dimensions ``dims`` = (bearing radius, journal radius, axial length) (m).

    Each row is an accepted step with penetration ``pen`` (m) at the contact direction, ``phib``,
    ``phij`` in each body's frame. The contact kernel puts it where the overlap
    f(psi) = |e| cos(psi - alpha) - h_b - h_j is largest, so f'(psi*) = 0 and f(psi*) = pen + clear:
    |e| cos(gamma) = pen + clear + h_b + h_j and |e| sin(gamma) = -(h_b' + h_j') give the eccentricity
    and gamma = psi* - alpha. The overlap o(d) = f(psi* + d) - clear > 0 around psi* is the
    elastic-foundation pressure shape; it is sampled every quarter region (of the finer surface) and
    added to the two nearest region centres of both surfaces (linear weights: the volume is exact).
    Samples step through region coordinates and rotate |e| (cos, sin) by the step: no angle is
    divided, wrapped or passed to cos per sample.
    """
    r1, r2, length = dims
    nb, nj = sb.size, sj.size
    mb, mj = node_slopes(sb, nb), node_slopes(sj, nj)  # depth_eval's values, without its divisions
    step = 0.5 * np.pi / max(nb, nj)
    smax = int(0.5 * np.pi / step)
    qb, qj = step * nb / (2.0 * np.pi), step * nj / (2.0 * np.pi)  # a step in region units
    cos_step, sin_step = math.cos(step), math.sin(step)
    wts = np.zeros(2 * smax + 1)
    for r in range(pen.size):
        xb, xj = region_coordinate(phib[r], nb), region_coordinate(phij[r], nj)
        hb, db, _ = table_eval(sb, mb, nb, xb)
        hj, dj, _ = table_eval(sj, mj, nj, xj)
        a = pen[r] + clear + hb + hj
        b = -(db + dj)
        emag = np.sqrt(a * a + b * b)
        gamma = np.arctan2(b, a)
        wts[smax] = max(pen[r], 0.0)
        lo = smax
        hi = smax
        for sign in (-1, 1):
            c, sn = emag * math.cos(gamma), emag * math.sin(gamma)  # |e| (cos, sin)(gamma + d), rotated by step
            for s in range(1, smax + 1):
                c, sn = c * cos_step - sign * sn * sin_step, sn * cos_step + sign * c * sin_step
                o = (c - table_value(sb, mb, nb, rewrap(xb + sign * s * qb, nb))
                     - table_value(sj, mj, nj, rewrap(xj + sign * s * qj, nj)) - clear)
                if o <= 0.0:
                    break
                wts[smax + sign * s] = o
                if sign < 0:
                    lo = smax - s
                else:
                    hi = smax + s
        total = 0.0
        for s in range(lo, hi + 1):
            total += wts[s]
        if total <= 0.0:  # grazing contact: all of it at the contact direction
            wts[smax] = 1.0
            total = 1.0
        db_ = vol_b[r] / (length * r1 * 2.0 * np.pi / nb) / total
        dj_ = vol_j[r] / (length * r2 * 2.0 * np.pi / nj) / total
        for s in range(lo, hi + 1):
            _bin(out_b, nb, rewrap(xb + (s - smax) * qb, nb), db_ * wts[s])
            _bin(out_j, nj, rewrap(xj + (s - smax) * qj, nj), dj_ * wts[s])
            wts[s] = 0.0


@njit(cache=True, inline="always")
def _bin(out, n, x, depth):
    """Add ``depth`` (m) at region coordinate x in [0, n] to the two nearest region centres (linear
    weights: the sum over regions, hence the volume, is exact)."""
    i0, i1, f = region_interval(x, n)
    out[i0] += depth * (1.0 - f)
    out[i1] += depth * f


def accumulate_wear(record: pd.DataFrame, law: WearLaw, regions: int = 1000, *,
                    cycles: float = 0.0, label: str = "", surfaces: JointSurfaces | None = None) -> JointSurfaces:
    """Wear depths (m) per region from one joint's contact record (paper eq. 18-21).

    ``record``: one row per accepted step, in time order, with columns ``dt`` (s), ``fn`` (N),
    ``omega_rel`` (rad/s, journal minus bearing), ``vt`` (m/s), ``phi_bearing``, ``phi_journal``
    (rad, contact direction in each body's frame at the end of the step). Rows with fn <= 0 wear
    nothing. With the ``"pressure"`` footprint (the record needs a ``pen`` column) each step's Archard
    volume goes over the arc where the surfaces the record was simulated on (``surfaces``, default
    unworn with ``regions`` regions) overlap (see :func:`_overlap_deposit`). With ``"hertz"`` a step's wear is spread along the arc the contact
    direction swept since the previous row (see :func:`_swept_deposit`); ``"region"`` puts it in
    the region at the step's end, as the paper does. Returns the surfaces worn by that record alone
    (add them to the previous state), with ``cycles`` and ``label`` as given.
    """
    missing = {"dt", "fn", "omega_rel", "phi_bearing", "phi_journal"} - set(record.columns)
    if missing:
        raise ValueError(f"contact record lacks columns {sorted(missing)}")
    on = record["fn"].to_numpy() > 0
    rec = record[on]
    fn = rec["fn"].to_numpy(float)
    vt = rec["vt"].to_numpy(float) if "vt" in rec else np.zeros_like(fn)
    bad = ~np.isfinite(fn) | ~np.isfinite(rec["dt"].to_numpy(float))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"contact record row at t = {rec['t'].iloc[i] if 't' in rec else i}: "
                         f"non-finite fn = {fn[i]} or dt")
    h = law.depth_increments(fn, rec["dt"].to_numpy(float), rec["omega_rel"].to_numpy(float), vt)
    if law.footprint == "pressure":
        if "pen" not in rec:
            raise ValueError("contact record lacks column 'pen' (needed by the pressure footprint)")
        base = surfaces if surfaces is not None else JointSurfaces.unworn(regions)
        ds = sliding_distance(rec["dt"].to_numpy(float), rec["omega_rel"].to_numpy(float), vt,
                              law.bearing_radius, law.sliding)
        vol = law.coefficient * fn * ds  # eq. 15 per step: V = K_n F dS (m^3)
        out_b, out_j = np.zeros(base.bearing.size), np.zeros(base.journal.size)
        _overlap_deposit(base.bearing, base.journal, law.bearing_radius - law.journal_radius,
                         rec["pen"].to_numpy(float), rec["phi_bearing"].to_numpy(float),
                         rec["phi_journal"].to_numpy(float), law.split * vol, (1 - law.split) * vol,
                         (law.bearing_radius, law.journal_radius, law.axial_length), out_b, out_j)
        return JointSurfaces(np.maximum(out_b, 0.0), np.maximum(out_j, 0.0), cycles, label)
    scale = regions / (2 * np.pi)
    sides = []
    for col, share, radius in (("phi_bearing", law.split, law.bearing_radius),
                               ("phi_journal", 1 - law.split, law.journal_radius)):
        phi = record[col].to_numpy(float)
        end = np.mod(phi[on], 2 * np.pi) * scale
        if law.footprint == "region":
            depth = np.zeros(regions)
            np.add.at(depth, np.floor(end).astype(int) % regions, share * h)
        else:
            swept = np.mod(np.diff(phi, prepend=phi[:1]) + np.pi, 2 * np.pi) - np.pi  # rad, in (-pi, pi]
            sweep = swept[on] * scale
            half = np.minimum(law.half_width(fn) / radius * scale, 0.49 * regions)
            depth = _swept_deposit(regions, end - sweep, sweep, half, share * h)
        sides.append(depth)
    return JointSurfaces(np.maximum(sides[0], 0.0), np.maximum(sides[1], 0.0), cycles, label)


def worn_volume(surfaces: JointSurfaces, law: WearLaw) -> float:
    """Material removed from bearing and journal together (m^3): sum of depth x region arc x L.

    Small-depth approximation (depth << radius), consistent with Archard's V = K_n F S (eq. 15).
    """
    arc_b = 2 * np.pi * law.bearing_radius / surfaces.bearing.size
    arc_j = 2 * np.pi * law.journal_radius / surfaces.journal.size
    return float((surfaces.bearing.sum() * arc_b + surfaces.journal.sum() * arc_j) * law.axial_length)
