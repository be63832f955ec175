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

from numba import njit
from wearbench.bench.schema import CONTACT_LAWS, STIFFNESS_FORMS

__all__ = [
    "FLORES",
    "HERTZ",
    "LANKARANI_NIKRAVESH",
    "LAWS",
    "MIN_IMPACT_SPEED",
    "STIFFNESS_FORMS",
    "conformal_radius",
    "contact_stiffness",
    "effective_modulus",
    "friction_factor",
    "friction_force",
    "impact_speed",
    "normal_force",
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
