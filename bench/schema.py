"""The bench schema: the frozen dataclasses a bench file is read into (see :mod:`wearbench.bench.load`).

A bench holds the mechanism (bodies, ground points, joints, which revolute joints have clearance
and with what radii and materials), the drivers, the sensors, the wear settings, the tolerances,
the candidate states and the hardware backend. Values are SI. Whether the mechanism assembles is
checked by ``wearbench.model`` when it builds a scene (it owns the kinematics).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

__all__ = [
    "AnalysisTable",
    "Bench",
    "BenchError",
    "Body",
    "Clearance",
    "ContactLaw",
    "Driver",
    "Frequency",
    "Hardware",
    "Joint",
    "Material",
    "Motor",
    "Sensor",
    "SensorChainStatement",
    "Tolerances",
    "WearSettings",
    "WearState",
]

GROUND = "frame"
CONTACT_LAWS = ("lankarani-nikravesh", "flores", "hertz")
STIFFNESS_FORMS = ("conformal", "paper")
BACKENDS = ("sim", "serial", "can", "canopen", "nidaqmx")


class BenchError(ValueError):
    """A bench file is wrong: names the file, the key, the value and what was expected."""

    def __init__(self, path: str | Path, key: str, value: Any, expected: str):
        self.path, self.key, self.value, self.expected = str(path), key, value, expected
        super().__init__(f"{path}: {key} = {value!r}: {expected}")


@dataclass(frozen=True)
class Material:
    name: str
    youngs_modulus: float  # Pa
    poisson_ratio: float
    hardness: float  # Pa
    density: float | None = None  # kg/m^3


@dataclass(frozen=True)
class ContactLaw:
    law: str = "lankarani-nikravesh"
    stiffness: str = "conformal"
    restitution: float = 0.9
    exponent: float = 1.5
    friction_coefficient: float = 0.1
    friction_v0: float = 1e-4  # m/s
    friction_vm: float = 1e-3  # m/s


@dataclass(frozen=True)
class Clearance:
    bearing_body: str
    journal_body: str
    bearing_radius: float  # m
    journal_radius: float  # m
    bearing_material: Material
    journal_material: Material
    axial_length: float  # m
    contact: ContactLaw
    surfaces: Path | None = None  # saved worn surfaces, if the bench names a worn state

    @property
    def radial_clearance(self) -> float:
        return self.bearing_radius - self.journal_radius


@dataclass(frozen=True)
class Body:
    name: str
    mass: float  # kg
    inertia: float  # kg m^2 about the centre of mass
    points: Mapping[str, tuple[float, float]]  # local coordinates from the centre of mass, m
    length: float | None = None  # m, for bars


@dataclass(frozen=True)
class Joint:
    name: str
    kind: str  # "revolute" | "prismatic"
    bodies: tuple[str, ...]  # two, or more for one pin shared by several bodies (revolute only)
    points: tuple[str, ...]
    axis: float | None = None  # prismatic: guide direction in the first body's frame, rad
    clearance: Clearance | None = None


@dataclass(frozen=True)
class Driver:
    joint: str
    ratio: float
    phase: float  # rad: angle at t = 0


@dataclass(frozen=True)
class SensorChainStatement:
    """What a lab states of an accelerometer's chain between the mechanism and its timestamps (the
    ``[sensor.chain]`` table of the sensor; host side: datasheets, calibration sheet, a tap test).

    The DAQ's anti-alias filter as ``filter`` (type), ``filter_order`` and ``filter_cutoff`` (Hz,
    -3 dB), or its datasheet group delay ``filter_delay`` (s); the sensor's mounted resonance
    (``resonance`` Hz, ``damping``) or its stated delay ``sensor_delay`` (s); ``latency``: the rest
    of the accelerometer's timestamps behind the encoder's (s, e.g. measured by a tap test);
    ``clock_drift``: the DAQ's sample clock against the encoder's (fraction, + = fast: its samples
    fall ever later behind their stamps); ``uncertainty`` (s) of the whole stated delay."""

    filter: str = "none"             # "butterworth" | "bessel" | "none"
    filter_order: int = 0
    filter_cutoff: float = 0.0       # Hz
    filter_delay: float | None = None  # s, the datasheet's group delay instead of type/order/cutoff
    resonance: float = 0.0           # Hz, 0 = none stated
    damping: float = 0.05
    sensor_delay: float | None = None  # s, the sensor's stated delay instead of its resonance
    latency: float = 0.0             # s
    clock_drift: float = 0.0         # fraction
    uncertainty: float = 1e-4        # s


@dataclass(frozen=True)
class Sensor:
    name: str
    kind: str  # "accelerometer" | "encoder"
    sample_rate: float  # Hz
    body: str | None = None
    point: str | None = None
    axis: float | None = None  # rad, measuring direction in the body frame
    range: float | None = None  # m/s^2
    sensitivity: float | None = None  # V per m/s^2
    joint: str | None = None
    counts_per_rev: int | None = None
    chain: SensorChainStatement | None = None  # accelerometer: the lab's statement of its chain


@dataclass(frozen=True)
class WearSettings:
    coefficient: float = 5e-15  # 1/Pa
    regions: int = 1000
    cycles_per_stage: int = 100
    stage_scale: float = 2000.0
    split: float = 0.5


@dataclass(frozen=True)
class Tolerances:
    """How a built bench differs from its file: one standard deviation of each quantity.

    A realisation draws each value from a normal distribution cut at 3 standard deviations (the
    ripple amplitude as its absolute value). The defaults are those of a machined lab bench: parts
    weighed to a few %, bores and pivots placed to a fraction of a mm, friction and restitution
    within the spread reported for dry steel/aluminium pairs, a servo drive's speed accuracy.
    """

    mass: float = 0.03          # relative, each body's mass
    inertia: float = 0.05       # relative, each body's moment of inertia
    length: float = 0.2e-3      # m, each coordinate of each body point (so link lengths and pin places)
    ground: float = 0.2e-3      # m, each coordinate of each ground point
    friction: float = 0.2       # relative, friction coefficient of each clearance joint
    restitution: float = 0.03   # absolute, restitution coefficient (kept in [0.7, 0.99])
    exponent: float = 0.05      # absolute, contact force exponent (kept in [1.0, 2.0])
    speed: float = 0.003        # relative, true motor speed against the commanded one
    ripple: float = 0.002       # relative, amplitude of the once-per-revolution speed ripple
    start: float = 0.3          # start state: journal velocity spread, in clearances per radian of crank


@dataclass(frozen=True)
class WearState:
    """A candidate state of the clearance joints: what identification chooses between."""

    name: str
    clearances: Mapping[str, float] = field(default_factory=dict)  # m, per joint; missing = bench's
    surfaces: Mapping[str, Path] = field(default_factory=dict)     # worn-surface files; missing = new


@dataclass(frozen=True)
class Frequency:
    """A frequency in the bench's own terms: ``value`` crank orders (``orders``: multiples of the
    encoder crank's frequency, so it moves with the crank speed) or ``value`` Hz (fixed)."""

    value: float
    orders: bool = True

    def hz(self, crank_hz: float) -> float:
        """The frequency (Hz) at a crank turning ``crank_hz`` revolutions per second."""
        return self.value * crank_hz if self.orders else self.value

    def describe(self) -> str:
        return f"{self.value:g} crank orders" if self.orders else f"{self.value:g} Hz"


@dataclass(frozen=True)
class AnalysisTable:
    """The ``[analysis]`` table: how the analysis of this bench's sessions scales with it, each key
    overriding one default rule of ``wearbench.validation.measurement.scaling`` (None: the rule's).
    Not physics: left out of the bench's content key (bench/content.py)."""

    bins: int | None = None                                      # crank-angle bins per revolution
    lowpass: Frequency | None = None                             # the features' curve low-pass
    lowpass_max: Frequency | None = None                         # ... at most this
    bands: tuple[tuple[Frequency, Frequency], ...] | None = None  # the impact bands (low, high)
    window_lowpass: Frequency | None = None                      # the windows' slow curves (delay fit, ISO)
    speeds: tuple[float, float] | None = None  # rad/s: the encoder crank's speeds the analysis is validated for


@dataclass(frozen=True)
class Motor:
    max_speed: float = 62.83  # rad/s
    max_acceleration: float = 200.0  # rad/s^2


@dataclass(frozen=True)
class Hardware:
    backend: str = "sim"
    options: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)  # per backend, raw


@dataclass(frozen=True)
class Bench:
    name: str
    description: str
    path: Path | None
    source: str  # the file's text, for MCAP attachments
    sha256: str
    speed: float  # rad/s, motor speed; driver i turns at ratio_i * speed
    gravity: tuple[float, float]
    ground_points: Mapping[str, tuple[float, float]]
    bodies: tuple[Body, ...]
    joints: tuple[Joint, ...]
    drivers: tuple[Driver, ...]
    sensors: tuple[Sensor, ...]
    materials: Mapping[str, Material]
    contact: ContactLaw
    wear: WearSettings
    motor: Motor
    hardware: Hardware
    assembly: Mapping[str, tuple[float, float]]  # joint name -> position at t = 0
    emulator: Mapping[str, Any] = field(default_factory=dict)  # raw [emulator] table (hardware/)
    tolerances: Tolerances = field(default_factory=Tolerances)
    states: tuple[WearState, ...] = ()  # named candidate states ([[state]] tables)
    # [compute] scheduler: where batches on this bench run ("local" or "tcp://HOST:PORT"); not physics,
    # so not part of the bench's content (bench/content.py)
    scheduler: str | None = field(default=None, repr=False)
    # [analysis]: how the analysis scales with this bench (validation.measurement.scaling); not physics
    analysis: AnalysisTable = field(default_factory=AnalysisTable, repr=False)

    def body(self, name: str) -> Body:
        for b in self.bodies:
            if b.name == name:
                return b
        raise KeyError(name)

    def joint(self, name: str) -> Joint:
        for j in self.joints:
            if j.name == name:
                return j
        raise KeyError(name)

    def sensor(self, kind: str) -> Sensor:
        """The sensor of ``kind`` ("accelerometer" or "encoder"): a bench has at most one of each (the
        loader refuses a second)."""
        for s in self.sensors:
            if s.kind == kind:
                return s
        raise KeyError(f"{self.name}: no {kind} sensor")

    @property
    def encoder_driver(self) -> Driver:
        """The driver whose crank the encoder reads (the loader refuses an encoder on any other joint);
        the first driver on a bench without an encoder."""
        joint = next((s.joint for s in self.sensors if s.kind == "encoder" and s.joint), None)
        return next((d for d in self.drivers if d.joint == joint), self.drivers[0])

    @property
    def clearance_joints(self) -> tuple[Joint, ...]:
        return tuple(j for j in self.joints if j.clearance is not None)

    def with_speed(self, speed: float) -> Bench:
        """The same bench at motor speed ``speed`` (rad/s)."""
        return replace(self, speed=float(speed))

    def with_clearances(self, clearances: Mapping[str, float | None]) -> Bench:
        """The same bench with radial clearances (m) by joint name; ``None`` makes a joint ideal.

        The bearing radius is kept and the journal radius becomes bearing radius - clearance.
        """
        joints = []
        names = {j.name for j in self.clearance_joints}
        unknown = set(clearances) - names
        if unknown:
            raise KeyError(f"{self.name}: no clearance joint {sorted(unknown)}; joints with clearance: {sorted(names)}")
        for j in self.joints:
            if j.name in clearances:
                c = clearances[j.name]
                if c is None:
                    j = replace(j, clearance=None)
                else:
                    if not 0 < c < j.clearance.bearing_radius:
                        raise ValueError(f"{self.name}: clearance {j.name} = {c} m: expected 0 < c < bearing radius "
                                         f"{j.clearance.bearing_radius} m")
                    j = replace(j, clearance=replace(j.clearance, journal_radius=j.clearance.bearing_radius - c))
            joints.append(j)
        return replace(self, joints=tuple(joints))
