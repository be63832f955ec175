"""Contact and friction laws of a revolute clearance joint: small pure functions on scalars.

Holds the contact geometry (effective modulus and conformal radius), the contact stiffness (eq. 10
and the conformal form), the normal force laws
(Lankarani-Nikravesh eq. 7-11, Flores et al. 2011, Hertz), the modified Coulomb friction
(eq. 12-13) and the worn-surface depth interpolation (periodic PCHIP, C1). Equation numbers are the paper's
("Dynamic characteristics and test research of multibody system considering uneven wear
clearances"). Every function is numba-compiled (``@njit``) so the integrator kernel calls the same
code the tests call from Python. Imports numpy, numba, math and the bench's vocabulary of laws.

Units: SI (m, N, Pa, s, rad).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from wearbench.bench.schema import CONTACT_LAWS, STIFFNESS_FORMS
from wearbench.model.jit_cache import configure_numba_cache

# every compiled module of the model imports this one first: the cache is keyed on the model's
# source before the first kernel is decorated
configure_numba_cache()

__all__ = [
    "FLORES",
    "HERTZ",
    "LANKARANI_NIKRAVESH",
    "LAWS",
    "MIN_IMPACT_SPEED",
    "STIFFNESS_FORMS",
    "conformal_radius",
    "contact_stiffness",
    "depth_at",
    "depth_eval",
    "depth_slope",
    "effective_modulus",
    "friction_factor",
    "friction_force",
    "hermite",
    "impact_speed",
    "node_slopes",
    "normal_force",
    "region_coordinate",
    "region_interval",
    "rewrap",
    "table_depth",
    "table_depth_eval",
    "table_eval",
    "table_value",
]

LAWS = {name: code for code, name in enumerate(CONTACT_LAWS)}  # the kernel's law codes
LANKARANI_NIKRAVESH, FLORES, HERTZ = LAWS["lankarani-nikravesh"], LAWS["flores"], LAWS["hertz"]
MIN_IMPACT_SPEED = 1e-3  # m/s: floor of the impact speed in the hysteresis damping (see impact_speed)


def _compliance(e1: float, nu1: float, e2: float, nu2: float) -> float:
    return (1.0 - nu1 ** 2) / e1 + (1.0 - nu2 ** 2) / e2


def effective_modulus(e1: float, nu1: float, e2: float, nu2: float) -> float:
    """Contact modulus E* (Pa): 1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2.

    Johnson, *Contact Mechanics* (1985), eq. 4.22 / 5.39 (plane strain, two elastic bodies).
    """
    return 1.0 / _compliance(e1, nu1, e2, nu2)


def conformal_radius(r1: float, r2: float) -> float:
    """Effective radius R* (m) of a journal of radius ``r2`` inside a bearing of radius ``r1``.

    Internal (conformal) contact: 1/R* = 1/R2 - 1/R1, i.e. R* = R1 R2/(R1 - R2) (Johnson 1985, 4.2).
    """
    if not r1 > r2 > 0:
        raise ValueError(f"conformal radius: expected bearing radius {r1} m > journal radius {r2} m > 0")
    return r1 * r2 / (r1 - r2)


def contact_stiffness(e1: float, nu1: float, e2: float, nu2: float, r1: float, r2: float,
                      form: str = "conformal") -> float:
    """Generalised contact stiffness K (N/m^n) of a journal (radius r2) in a bearing (radius r1).

    K = 4 / (3 (s1 + s2)) * sqrt(R), s_i = (1 - nu_i^2) / E_i (Pa^-1).

    - ``"conformal"`` (default): R = r1 r2 / (r1 - r2). A journal inside a bearing is an *internal*
      contact of two nearly conformal cylinders: the curvatures subtract, so the effective radius
      is r1 r2 / (r1 - r2) (Johnson, Contact Mechanics, sec. 4.2; Flores et al., Lankarani and
      Nikravesh use this form for clearance joints). At 15 mm / 0.6 mm it is ~7x stiffer.
    - ``"paper"``: R = r1 r2 / (r1 + r2), the paper's eq. 10 as printed (external contact of two
      convex cylinders), kept to reproduce the paper's numbers.
    """
    s = _compliance(e1, nu1, e2, nu2)
    if form == "conformal":
        radius = conformal_radius(r1, r2)
    elif form == "paper":
        radius = r1 * r2 / (r1 + r2)
    else:
        raise ValueError(f"stiffness form {form!r}: expected one of {list(STIFFNESS_FORMS)}")
    return 4.0 / (3.0 * s) * math.sqrt(radius)


@njit(cache=True)
def impact_speed(vn_onset: float) -> float:
    """Impact speed v0 (m/s) used in the hysteresis damping: max(|vn at onset|, MIN_IMPACT_SPEED).

    The damping D of eq. 11 grows as 1/v0; a contact that starts at zero normal velocity (a journal
    resting on its bearing) would divide by zero. Below 1 mm/s the energy lost in the impact is
    negligible and the floor only bounds the damping.
    """
    v = abs(vn_onset)
    return max(MIN_IMPACT_SPEED, v)


@njit(cache=True)
def normal_force(pen: float, pen_rate: float, stiffness: float, exponent: float,
                 restitution: float, v_impact: float, law: int) -> float:
    """Normal contact force F_n (N, >= 0) for penetration ``pen`` (m) and its rate (m/s).

    law LANKARANI_NIKRAVESH (eq. 7-11): F = K d^n (1 + 3 (1 - ce^2) / 4 * d' / v0).
    law FLORES, Flores et al. (Nonlinear Dyn. 2011, valid for any ce):
    F = K d^n (1 + 8 (1 - ce) / (5 ce) * d' / v0).
    law HERTZ: F = K d^n (no damping).
    ``v_impact`` is the impact speed v0 > 0 (see :func:`impact_speed`). The force never pulls
    (clamped at 0 when the damping term exceeds the elastic one during restitution).
    """
    if pen <= 0.0:
        return 0.0
    elastic = stiffness * pen ** exponent
    if law == LANKARANI_NIKRAVESH:
        f = elastic * (1.0 + 0.75 * (1.0 - restitution * restitution) * pen_rate / v_impact)
    elif law == FLORES:
        f = elastic * (1.0 + 1.6 * (1.0 - restitution) / restitution * pen_rate / v_impact)
    else:
        f = elastic
    return max(0.0, f)


@njit(cache=True)
def friction_factor(vt: float, v0: float, vm: float) -> float:
    """Correction coefficient c_d of the modified Coulomb law (eq. 13): 0 below v0, ramp to 1 at vm."""
    s = abs(vt)
    if s <= v0:
        return 0.0
    if s >= vm:
        return 1.0
    return (s - v0) / (vm - v0)


@njit(cache=True)
def friction_force(fn: float, vt: float, cf: float, v0: float, vm: float) -> float:
    """Tangential friction force F_t (N) opposing the sliding velocity vt (m/s), eq. 12:
    F_t = -c_f c_d(vt) F_n sign(vt)."""
    if vt == 0.0:
        return 0.0
    return -cf * friction_factor(vt, v0, vm) * fn * (1.0 if vt > 0.0 else -1.0)


@njit(cache=True, inline="always")
def _pchip_node_slope(d0: float, d1: float) -> float:
    """PCHIP slope (per region) at a node from its left and right differences (Fritsch-Butland
    harmonic mean for equal spacing; zero at a local extremum, so no overshoot)."""
    if d0 * d1 <= 0.0:
        return 0.0
    return 2.0 * d0 * d1 / (d0 + d1)


@njit(cache=True, inline="always")
def hermite(y0: float, m0: float, y1: float, m1: float, f: float) -> float:
    """Cubic Hermite value at fraction ``f`` of an interval from node values and slopes (per region)."""
    f2 = f * f
    f3 = f2 * f
    return (2.0 * f3 - 3.0 * f2 + 1.0) * y0 + (f3 - 2.0 * f2 + f) * m0 + (-2.0 * f3 + 3.0 * f2) * y1 \
        + (f3 - f2) * m1


@njit(cache=True)
def node_slopes(depths: np.ndarray, n: int) -> np.ndarray:
    """The PCHIP node slopes (m per region) of :func:`depth_eval` for the first ``n`` depths, a table
    computed once per surface so the contact search can sample depths without recomputing them."""
    out = np.zeros(depths.size)
    for i in range(n):
        out[i] = _pchip_node_slope(depths[i] - depths[i - 1 if i > 0 else n - 1],
                                   depths[i + 1 if i + 1 < n else 0] - depths[i])
    return out


@njit(cache=True, inline="always")
def region_interval(x: float, n: int) -> tuple[int, int, float]:
    """The interval (centres i0, i1) holding region coordinate ``x`` in [0, n] (centre i at x = i,
    periodic) and the fraction in it; wrap other coordinates first (``x - n floor(x / n)``)."""
    i = int(x)
    f = x - i
    i0 = i if i < n else i - n  # cheap periodic neighbours (no signed modulo: the hot path)
    i1 = i0 + 1 if i0 + 1 < n else 0
    return i0, i1, f


@njit(cache=True, inline="always")
def table_value(depths: np.ndarray, slopes: np.ndarray, n: int, x: float) -> float:
    """Depth (m) at region coordinate ``x`` in [0, n] (node i at x = i, periodic), the value of
    :func:`depth_eval` at phi = 2 pi (x + 0.5) / n, from the :func:`node_slopes` table."""
    i0, i1, f = region_interval(x, n)
    return hermite(depths[i0], slopes[i0], depths[i1], slopes[i1], f)


@njit(cache=True, inline="always")
def table_depth(depths: np.ndarray, slopes: np.ndarray, n: int, x: float) -> float:
    """:func:`table_value` at any region coordinate ``x`` (wrapped first)."""
    return table_value(depths, slopes, n, x - n * math.floor(x / n))


@njit(cache=True, inline="always")
def region_coordinate(phi: float, n: int) -> float:
    """The region coordinate in [0, n] of body-frame angle ``phi`` (rad; centre i at i)."""
    x = phi * (n / (2.0 * math.pi)) - 0.5
    return x - n * math.floor(x / n)


@njit(cache=True, inline="always")
def rewrap(x: float, n: int) -> float:
    """A region coordinate within n of [0, n] wrapped into [0, n] by one comparison (a coordinate
    stepped from a wrapped one: no division)."""
    if x >= n:
        return x - n
    return x + n if x < 0.0 else x


@njit(cache=True, inline="always")
def _locate(n: int, phi: float) -> tuple[int, int, float]:
    """The interval (centres i0, i1) holding body-frame angle ``phi`` and the fraction in it."""
    return region_interval(region_coordinate(phi, n), n)


@njit(cache=True, inline="always")
def _hermite_eval(y0: float, m0: float, y1: float, m1: float, f: float, n: int) -> tuple[float, float, float]:
    """Depth and its first and second derivatives in phi at fraction ``f`` of an interval."""
    f2 = f * f
    h = hermite(y0, m0, y1, m1, f)
    dh = (6.0 * f2 - 6.0 * f) * (y0 - y1) + (3.0 * f2 - 4.0 * f + 1.0) * m0 + (3.0 * f2 - 2.0 * f) * m1
    d2h = (12.0 * f - 6.0) * (y0 - y1) + (6.0 * f - 4.0) * m0 + (6.0 * f - 2.0) * m1
    scale = n / (2.0 * math.pi)
    return h, dh * scale, d2h * scale * scale


@njit(cache=True)
def depth_eval(depths: np.ndarray, n: int, phi: float) -> tuple[float, float, float]:
    """Wear depth (m) at body-frame angle ``phi`` (rad) and its first and second derivatives
    (m/rad, m/rad^2): periodic PCHIP through the centres of ``n`` equal regions (region i covers
    [2 pi i/n, 2 pi (i+1)/n), its centre holds ``depths[i]``).

    PCHIP (piecewise cubic Hermite with Fritsch-Carlson/Butland slopes; Fritsch & Carlson, SIAM J.
    Numer. Anal. 17, 1980) is C1, so the depth, the contact normal and the penetration are
    continuous; it is local (four values per interval, no coefficients to precompute) and
    shape-preserving (no negative depths, no new extrema at the edge of a pit, which a C2 spline
    would add). The second derivative is piecewise linear (used by the contact search only).
    """
    i0, i1, f = _locate(n, phi)
    im = i0 - 1 if i0 > 0 else n - 1
    i2 = i1 + 1 if i1 + 1 < n else 0
    y0 = depths[i0]
    y1 = depths[i1]
    d = y1 - y0
    m0 = _pchip_node_slope(y0 - depths[im], d)
    m1 = _pchip_node_slope(d, depths[i2] - y1)
    return _hermite_eval(y0, m0, y1, m1, f, n)


@njit(cache=True, inline="always")
def table_eval(depths: np.ndarray, slopes: np.ndarray, n: int, x: float) -> tuple[float, float, float]:
    """Depth (m) and its first and second derivatives in phi at region coordinate ``x`` in [0, n]
    (see :func:`table_value`)."""
    i0, i1, f = region_interval(x, n)
    return _hermite_eval(depths[i0], slopes[i0], depths[i1], slopes[i1], f, n)


@njit(cache=True, inline="always")
def table_depth_eval(depths: np.ndarray, slopes: np.ndarray, n: int, phi: float) -> tuple[float, float, float]:
    """:func:`depth_eval` (the same values) with the node slopes read from the :func:`node_slopes`
    table instead of computed."""
    return table_eval(depths, slopes, n, region_coordinate(phi, n))


@njit(cache=True)
def depth_at(depths: np.ndarray, n: int, phi: float) -> float:
    """Wear depth (m) at body-frame angle ``phi`` (rad), periodic PCHIP (see :func:`depth_eval`)."""
    return depth_eval(depths, n, phi)[0]


@njit(cache=True)
def depth_slope(depths: np.ndarray, n: int, phi: float) -> float:
    """d(depth)/d(phi) (m/rad) of :func:`depth_at`, continuous in ``phi``."""
    return depth_eval(depths, n, phi)[1]
