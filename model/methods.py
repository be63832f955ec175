"""Integration methods as data: Butcher tableaus and the registry of methods.

As scipy's ``integrate/_ivp/rk.py`` does, each explicit Runge-Kutta method is its tableau
(:class:`Tableau`: :data:`DOPRI5`, :data:`RK4`), run by the one compiled step
``integrators.erk_try``. A :class:`Method` pairs a tableau with its step control and constraint
stabilisation; :data:`METHODS` is the registry ``simulate``, the command line's ``--method`` and
``benchmarks/model/work_precision.py`` read. Adding a method: its tableau here, an entry in
:data:`METHODS`. Imports numpy only (the command line reads it without loading numba).
"""

from __future__ import annotations

import dataclasses
from collections import namedtuple
from dataclasses import dataclass

import numpy as np

__all__ = ["DOPRI5", "DRIFT_TOLERANCE", "METHODS", "RK4", "TABLEAUS", "Accurate", "Dopri5", "Kinematics", "Method", "RK4Paper", "Scheme",
           "Tableau", "get_method"]

DRIFT_TOLERANCE = 1e-4  # m (or rad): largest position-constraint violation before a run stops

# a tableau as the compiled step reads it: ``end`` is the row of the stage array k (end + 1 rows) holding f
# at the end of the step; expo and expo_pi # the step controller's exponents (1 / (q + 1) with q the order of
# the embedded estimate, and 1 / (q + 1) - 0.75 * 0.04 for the PI controller); d the continuous extension
# (row per stage of k: coefficients of theta, theta^2, ...; no rows: none)
Scheme = namedtuple("Scheme", "a c b b_den e fsal stages nfev end expo expo_pi d")


@dataclass(frozen=True)
class Tableau:
    """An explicit Runge-Kutta method as data (Butcher tableau), run by the one compiled :func:`erk_try`.

    c: stage nodes; a: stage coefficients (row s uses k[0..s-1]); b: weights as exact numbers over a
    common denominator ``b_den`` (ignored with ``fsal``: the last stage is the solution); e: weights of
    the embedded error estimate (empty: a fixed-step method) of order ``error_order``. With ``fsal`` the
    last stage is evaluated at the new state, so its derivative starts the next step; without, one more
    evaluation at the new state follows the stages. Any number of stages.
    """

    name: str
    order: int
    c: tuple[float, ...]
    a: tuple[tuple[float, ...], ...]
    b: tuple[float, ...]
    b_den: float = 1.0
    e: tuple[float, ...] = ()
    fsal: bool = False
    error_order: int = 0
    dense: tuple[tuple[float, ...], ...] = ()
    reference: str = ""

    def __post_init__(self) -> None:
        stages = len(self.c)
        if len(self.a) != stages or any(len(row) > s for s, row in enumerate(self.a)):
            raise ValueError(f"tableau {self.name}: {stages} nodes; expected one row of a per stage, row s with at "
                             "most s entries (explicit)")
        if self.fsal and (self.c[-1] != 1.0 or tuple(self.a[-1]) != tuple(self.b[:stages - 1])):
            raise ValueError(f"tableau {self.name}: FSAL needs the last stage at c = 1 with the weights b as its row")
        if len(self.e) > stages + (0 if self.fsal else 1) or (self.e and self.error_order < 1):
            raise ValueError(f"tableau {self.name}: error weights for at most the stages and the end derivative, "
                             "and the embedded estimate's order error_order >= 1")
        if self.dense and (len(self.dense) != stages + (0 if self.fsal else 1)
                           or any(abs(sum(row) - w / self.b_den) > 1e-12
                                  for row, w in zip(self.dense, (*self.b, 0.0), strict=False))):
            raise ValueError(f"tableau {self.name}: the continuous extension needs one row per stage (and the "
                             "end derivative) whose coefficients sum to the weights b at theta = 1")

    @property
    def adaptive(self) -> bool:
        return len(self.e) > 0

    def scheme(self) -> Scheme:
        """The arrays the compiled step reads."""
        stages = len(self.c)
        end = stages - 1 if self.fsal else stages
        a = np.zeros((stages, end + 1))
        for s, row in enumerate(self.a):
            a[s, :len(row)] = row
        q1 = self.error_order + 1 if self.error_order else 5
        d = np.array(self.dense, dtype=float) if self.dense else np.zeros((0, 1))
        return Scheme(a=a, c=np.array(self.c, dtype=float), b=np.array(self.b, dtype=float), b_den=float(self.b_den),
                      e=np.array(self.e, dtype=float), fsal=self.fsal, stages=stages,
                      nfev=stages - 1 + (0 if self.fsal else 1), end=end, expo=1.0 / q1,
                      expo_pi=round(1.0 / q1 - 0.75 * 0.04, 12), d=d)


DOPRI5 = Tableau(
    "dopri5", 5,
    c=(0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0),
    a=((), (1 / 5,), (3 / 40, 9 / 40), (44 / 45, -56 / 15, 32 / 9),
       (19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729),
       (9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656),
       (35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84)),
    b=(35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84, 0),
    e=(71 / 57600, 0, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40),
    fsal=True, error_order=4,
    # Shampine's fourth-order continuous extension (Hairer, Norsett, Wanner, sec. II.6; Shampine, Math. Comp. 46,
    # 1986), b_i(theta) = sum_p dense[i][p] theta^(p + 1)
    dense=((1.0, -8048581381 / 2820520608, 8663915743 / 2820520608, -12715105075 / 11282082432),
           (0.0, 0.0, 0.0, 0.0),
           (0.0, 131558114200 / 32700410799, -68118460800 / 10900136933, 87487479700 / 32700410799),
           (0.0, -1754552775 / 470086768, 14199869525 / 1410260304, -10690763975 / 1880347072),
           (0.0, 127303824393 / 49829197408, -318862633887 / 49829197408, 701980252875 / 199316789632),
           (0.0, -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844),
           (0.0, 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423)),
    reference="Dormand-Prince 5(4): Hairer, Norsett, Wanner, Solving ODE I, table II.5.2")
RK4 = Tableau(
    "rk4", 4, c=(0.0, 0.5, 0.5, 1.0), a=((), (0.5,), (0.0, 0.5), (0.0, 0.0, 1.0)), b=(1, 2, 2, 1), b_den=6.0,
    reference="classical Runge-Kutta 4 (the paper's integrator)")
TABLEAUS = {t.name: t for t in (DOPRI5, RK4)}


@dataclass(frozen=True)
class Method:
    """An integration method: its step kernel, step control and constraint stabilisation.

    tableau: the explicit Runge-Kutta tableau the compiled loop steps with (None: no time integration,
    the kinematics method); adaptive: error-controlled
    step (the tableau's embedded estimate; else fixed ``step``); project: coordinate projection onto the position and velocity constraints after
    every accepted step (drift-free); baumgarte: (alpha, beta) of eq. 30; drift_tolerance: the largest
    position-constraint violation (m or rad) before a run stops with an error.
    """

    name: str
    tableau: Tableau | None
    adaptive: bool
    project: bool
    baumgarte: tuple[float, float] = (0.0, 0.0)
    rtol: float = 1e-6
    atol: float = 1e-9
    step: float | None = None  # s, fixed step (or first step of an adaptive method)
    drift_tolerance: float = DRIFT_TOLERANCE  # m (or rad): the run stops with an error beyond this drift
    doc: str = ""


Dopri5 = Method(
    name="default", tableau=DOPRI5, adaptive=True, project=True, rtol=1e-6, atol=1e-9,
    doc="Dormand-Prince 5(4), adaptive error-controlled step (PI control), coordinate projection "
        "onto the position and velocity constraints after any accepted step with measurable drift "
        "(drift-free); contact onsets and impacts are resolved by step rejection. rtol 1e-6, atol 1e-9 m: "
        "peak contact forces within ~2 %; the clearance dynamics are chaotic, so pointwise agreement "
        "over a whole revolution is out of reach for every method (see benchmarks/model/work_precision.py).",
)
Accurate = dataclasses.replace(
    Dopri5, name="accurate", rtol=1e-8, atol=1e-11,
    doc="The default method at rtol 1e-8, atol 1e-11 m: <= ~1 % RMS slider-acceleration error over the "
        "predictable horizon, ~2x the default's cost; slow on sharply stepped worn surfaces.",
)
RK4Paper = Method(
    name="rk4-paper", tableau=RK4, adaptive=False, project=False, baumgarte=(20.0, 20.0), step=1e-4,
    doc="The paper's method: classical Runge-Kutta 4, fixed step 1e-4 s, Baumgarte alpha = beta = 20.",
)
Kinematics = Method(
    name="kinematics", tableau=None, adaptive=False, project=True,
    doc="No time integration: position, velocity and acceleration analysis plus inverse dynamics at each "
        "output time (a fully driven mechanism with ideal joints only; what 'default' does for such a scene).",
)
METHODS: dict[str, Method] = {m.name: m for m in (Dopri5, Accurate, RK4Paper, Kinematics)}
METHODS["dopri5"] = Dopri5


def get_method(name: str) -> Method:
    """The method registered as ``name`` ("default", "dopri5", "accurate", "rk4-paper", "kinematics");
    ValueError if unknown."""
    try:
        return METHODS[name]
    except KeyError:
        raise ValueError(f"unknown method {name!r}: expected one of {sorted(METHODS)}") from None
