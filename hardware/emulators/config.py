"""The ``[emulator]`` table of a bench file: imperfections, hidden truth and fault injection.

:class:`EmulatorConfig` is what :class:`~wearbench.hardware.emulators.device.BenchDevice` runs
with. Every value is validated; a mistake raises :class:`~wearbench.bench.schema.BenchError`
naming the file, the key, the value and what was expected. Every imperfection can be switched off
(0, "0 ppm", false, or leaving the key out: the defaults are a clean device). Fault times count
from the first START_STREAM. Imports only the bench module and the carriage's.

Example::

    [emulator]
    signal = "model"            # "model" | "harmonic" (test pattern) | "white" (shaker) | "none"
    revolutions = 40            # non-twin truth: revolutions of the run the device plays (then wraps)
    settle = 2                  # revolutions simulated and dropped before them
    [emulator.accelerometer]
    noise = "0.05 m/s^2"        # white noise std
    bias = "0.2 m/s^2"
    clipping = true             # clip at the configured full-scale range
    adc_bits = 16               # 0 = no quantisation (float samples)
    drift = "40 ppm"            # sample clock runs fast by this much
    resonance = "1.5 kHz"       # mounting transfer: structural resonance of the mount (second order)
    damping = 0.05
    aa_filter = "butterworth"   # anti-alias low-pass before sampling: "butterworth" | "bessel" | "none"
    aa_order = 8
    aa_cutoff = 0.3             # -3 dB frequency as a fraction of the sample rate
    sensitivity = 1.0           # true sensitivity / the bench file's (a sensor off by a few %)
    cross_axis = 0.0            # the sensor's output per unit lateral acceleration / its sensitivity (signed;
                                # 0 = off): the in-plane part of a datasheet's 1-5 % cross-axis sensitivity
    lateral_mode = "1.2 kHz"    # the carriage's lateral mode on its guide (needed with cross_axis; 0 = rigid)
    lateral_damping = 0.05
    [emulator.accelerometer.spread]  # a sensor path drawn per truth seed (replaces the six keys above)
    mode = ["300 Hz", "3 kHz"]  # structural mode of the mount or carriage: log-uniform in this range
    damping = [0.02, 0.1]       # its damping ratio: uniform in this range
    sensitivity = 0.05          # sensitivity error: uniform within +/- this fraction
    cross_axis = [0.01, 0.05]   # cross-axis sensitivity: magnitude uniform in this range, at an angle
                                # uniform on the circle (cross_axis = its magnitude x cos(angle)); [0, 0] = off
    lateral_mode = ["300 Hz", "3 kHz"]  # the carriage's lateral mode: log-uniform in this range
    lateral_damping = [0.02, 0.1]       # its damping ratio: uniform in this range
    [emulator.motor]
    ripple = 0.01               # relative speed ripple, harmonic per motor revolution below
    ripple_harmonic = 1
    [emulator.encoder]
    index = true
    index_angle = "0 deg"       # crank angle of the index pulse
    [emulator.truth]            # what the device really has, whatever the host claims
    seed = 7                    # a bench drawn from [tolerances] (non-twin); absent or twin = true: the nominal model
    state = "0.3 mm first wear" # a [[state]] of the bench (its clearances and wear) ...
    clearances = { A = "0.32 mm", B = "0.28 mm" }  # ... or the clearances and wear themselves
    wear = { A = "worn-A.npz" } # worn surfaces (JointSurfaces .npz, relative to the bench file)
    wear_stage = "first wear"
    accel_delay = "0.5 ms"      # accelerometer signal delay behind the crank angle
    [emulator.faults]
    drop_rate = 0.001           # fraction of stream blocks lost
    corrupt_rate = 0.001        # fraction of serial frames with one byte flipped
    disconnect_after = "5 s"    # the link dies this long after streaming starts
    stall_at = "3 s"            # the motor stalls (latched fault)
    bus_off_at = "2 s"          # CAN controller goes bus-off ...
    bus_off_duration = "0.2 s"  # ... for this long
    reply_delay = "0.3 s"       # every command reply is late by this much
    garbage_at = "2 s"          # a burst of random bytes on the line (CAN: malformed frames) ...
    garbage_bytes = 256         # ... this many bytes
    freeze_at = "2 s"           # the device firmware hangs: no data, no replies, the link stays open
    index_lost_at = "2 s"       # the encoder's index pulse stops (broken index line); counts go on

The same table as JSON (``wearbench emulate --config FILE.json``, ``wearbench record --option
config=FILE.json`` on the ``sim`` backend, the ``sim`` backend's ``config`` option): one object of the
same keys, its sub-tables as objects, values with units as strings, e.g.
``{"truth": {"state": "0.6 mm new", "seed": 3}, "accelerometer": {"noise": "0.1 m/s^2"}}``. It replaces
the bench file's table as a whole (keys left out take the defaults above, not the bench file's).
Every key is checked, in JSON as in TOML: an unknown key or a bad value raises BenchError naming the
file, the key (``emulator.truth.state``), the value and what was expected.

The truth and a session's labels (``wearbench record --clearance/--wear``): the ``sim`` backend's
emulator, run by the recorder itself, plays what the labels say (:meth:`Truth.labelled`: the labelled
joints' clearances and wear set, the rest of the truth kept, its seed and delay too) and the command
says so; a serial emulator's truth is set where it runs (this table, ``wearbench emulate --state``) and
its INFO name carries the marks of it (:meth:`Truth.marks`, ``hardware/protocol/truth.py``), so the
recorder refuses a label it does not play (``acquisition/emulated_truth.py``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from wearbench.bench.content import file_digest
from wearbench.bench.load import TomlReader
from wearbench.bench.schema import Bench, WearState
from wearbench.hardware.emulators.carriage import carriage
from wearbench.hardware.protocol.truth import clearance_mark, wear_mark

__all__ = [
    "AA_FILTERS",
    "SIGNALS",
    "Accelerometer",
    "EmulatorConfig",
    "EncoderImperfections",
    "Faults",
    "MotorImperfections",
    "SensorSpread",
    "Truth",
    "emulator_config",
]

SIGNALS = ("model", "harmonic", "white", "none")
AA_FILTERS = ("none", "butterworth", "bessel")
DEFAULT_REVOLUTIONS = 40  # non-twin run: 20-cycle sessions plus their start-up play without a wrap
_CROSS_AXIS_LIMIT = 0.2  # |cross-axis sensitivity|: datasheets give 1-5 %, a damaged sensor more


@dataclass(frozen=True)
class Accelerometer:
    noise: float = 0.0        # m/s^2 std
    bias: float = 0.0         # m/s^2
    clipping: bool = True
    adc_bits: int = 16        # 0 = off
    drift: float = 0.0        # fraction (ppm * 1e-6), + = sample clock fast
    resonance: float = 0.0    # Hz, 0 = no mounting transfer
    damping: float = 0.05     # damping ratio of the mounting resonance
    white_level: float = 10.0  # m/s^2 rms of the "white" test signal (at the chain's internal rate)
    aa_filter: str = "none"   # anti-alias low-pass before sampling: "butterworth" | "bessel" | "none"
    aa_order: int = 8
    aa_cutoff: float = 0.3    # -3 dB frequency / sample rate
    sensitivity: float = 1.0  # true sensitivity / the bench file's (a gain on the signal)
    cross_axis: float = 0.0   # output per unit lateral carriage acceleration / the main-axis sensitivity (signed)
    lateral_mode: float = 0.0  # Hz, the carriage's lateral mode on its guide (0 = a rigid guide)
    lateral_damping: float = 0.05  # its damping ratio
    spread: SensorSpread | None = None  # drawn sensor paths (applied by EmulatorConfig for a seeded truth)

    @property
    def lateral(self) -> bool:
        """Whether the carriage's lateral motion reaches the output (a cross-axis sensitivity and a mode)."""
        return self.cross_axis != 0.0 and self.lateral_mode > 0.0


@dataclass(frozen=True)
class SensorSpread:
    """How the sensor path of a drawn truth differs from the bench file's: a structural mode of the
    mount or carriage (second order, like ``resonance``) with its frequency log-uniform in ``mode``
    (Hz) and its damping ratio uniform in ``damping``; the sensitivity uniform within +/-
    ``sensitivity``; a cross-axis sensitivity of magnitude uniform in ``cross_axis`` at an angle uniform
    on the circle (its in-plane part, magnitude x cos(angle), is what the lateral direction sees) and the
    carriage's lateral mode log-uniform in ``lateral_mode`` (Hz) with damping uniform in
    ``lateral_damping``. Drawn from the truth's seed, so every session of one drawn bench shares its path
    (as sessions of one bench with one mount do); the cross-axis part from a stream of its own, so a
    seed's axial path is the same with and without it."""

    mode: tuple[float, float] = (300.0, 3000.0)
    damping: tuple[float, float] = (0.02, 0.1)
    sensitivity: float = 0.05
    cross_axis: tuple[float, float] = (0.01, 0.05)
    lateral_mode: tuple[float, float] = (300.0, 3000.0)
    lateral_damping: tuple[float, float] = (0.02, 0.1)

    def draw(self, acc: Accelerometer, seed: int) -> Accelerometer:
        """``acc`` with the path of truth ``seed`` (resonance, damping, sensitivity, cross_axis,
        lateral_mode and lateral_damping replaced)."""
        rng = np.random.default_rng([int(seed), 0x5E45])
        mode = _log_uniform(rng, self.mode)
        axial = replace(acc, resonance=mode, damping=float(rng.uniform(*self.damping)),
                        sensitivity=float(1.0 + rng.uniform(-self.sensitivity, self.sensitivity)))
        rng = np.random.default_rng([int(seed), 0x5E46])
        size, angle = rng.uniform(*self.cross_axis), rng.uniform(0.0, 2.0 * np.pi)
        lateral = _log_uniform(rng, self.lateral_mode)
        return replace(axial, cross_axis=float(size * np.cos(angle)), lateral_mode=lateral,
                       lateral_damping=float(rng.uniform(*self.lateral_damping)))


def _log_uniform(rng: np.random.Generator, bounds: tuple[float, float]) -> float:
    lo, hi = bounds
    return float(np.exp(rng.uniform(np.log(lo), np.log(hi)))) if hi > lo else lo


@dataclass(frozen=True)
class MotorImperfections:
    ripple: float = 0.0       # relative speed ripple amplitude
    ripple_harmonic: int = 1  # ripple periods per motor revolution


@dataclass(frozen=True)
class EncoderImperfections:
    index: bool = True
    index_angle: float = 0.0  # rad, crank angle (encoder joint) at which the index pulse fires


@dataclass(frozen=True)
class Truth:
    """What the device really is. ``seed`` None: the nominal bench, one steady revolution looped
    (a twin of the model); a seed: the bench drawn from its ``[tolerances]`` with that seed, played
    as a long run with cycle-to-cycle variation (see :mod:`wearbench.hardware.emulators.signal`)."""

    clearances: Mapping[str, float] = field(default_factory=dict)  # m, per joint; missing = bench's
    wear: Mapping[str, Path] = field(default_factory=dict)         # worn surfaces per joint
    wear_stage: str = ""
    accel_delay: float = 0.0  # s
    seed: int | None = None

    @property
    def twin(self) -> bool:
        return self.seed is None

    def state(self) -> WearState:
        """The truth's clearances and wear as a candidate state (named by its wear stage)."""
        return WearState(self.wear_stage or "truth", dict(self.clearances), dict(self.wear))

    def joints(self, bench: Bench) -> dict[str, tuple[float, Path | None]]:
        """What the device plays at each clearance joint of ``bench``: (radial clearance m, worn-surface
        file or None for new). A joint the truth leaves out keeps the bench file's clearance; a truth
        without wear keeps the surfaces the bench file's joints name (as a [[state]] does)."""
        out = {}
        for j in bench.clearance_joints:
            worn = self.wear.get(j.name) if self.wear else j.clearance.surfaces
            out[j.name] = (float(self.clearances.get(j.name, j.clearance.radial_clearance)),
                           None if worn is None else Path(worn))
        return out

    def marks(self, bench: Bench) -> dict[str, tuple[str, str]]:
        """The marks of the truth by joint (hardware/protocol/truth.py): a host checks a claim by them."""
        return {j: (clearance_mark(bench.name, j, c), wear_mark(bench.name, j, None if w is None else file_digest(w)))
                for j, (c, w) in self.joints(bench).items()}

    def describe(self, bench: Bench) -> str:
        """The truth in words, e.g. ``A 0.3 mm worn (A_200k.npz), B 0.3 mm new; drawn with seed 1``."""
        joints = ", ".join(f"{j} {c * 1e3:.4g} mm " + ("new" if w is None else f"worn ({Path(w).name})")
                           for j, (c, w) in self.joints(bench).items())
        return f"{joints}; " + ("the model's twin" if self.twin else f"drawn with seed {self.seed}")

    def labelled(self, bench: Bench, clearances: Mapping[str, float], wear: Mapping[str, Path | None]) -> Truth:
        """This truth with the clearances (m) and wear (a worn-surface file, None for new) of the joints
        given set, the rest kept (its seed and delay too); itself when nothing changes. The stage is
        the name of the bench's [[state]] it then equals, else "as recorded". ValueError where it cannot
        be set: a joint made new whose bench file names worn surfaces for it."""
        now = self.joints(bench)
        unknown = sorted((set(clearances) | set(wear)) - set(now))
        if unknown:
            raise ValueError(f"{bench.name}: no clearance joint {unknown}; joints with clearance: {sorted(now)}")
        new = {j: (float(clearances.get(j, c)), wear.get(j, w)) for j, (c, w) in now.items()}
        if _same(bench, new, now):
            return self
        worn = {j: Path(w).resolve() for j, (c, w) in new.items() if w is not None}
        if not worn:
            kept = [j.name for j in bench.clearance_joints if j.clearance.surfaces is not None]
            if kept:
                raise ValueError(f"{bench.path or bench.name}: joint {kept[0]} is worn by the bench file's "
                                 "[joint.clearance] surfaces; the emulator's truth cannot make every joint new")
        stage = next((s.name for s in bench.states if _same(bench, new, Truth(s.clearances, s.surfaces).joints(bench))),
                     "as recorded")
        return replace(self, clearances={j: c for j, (c, w) in new.items()}, wear=worn, wear_stage=stage)


def _same(bench: Bench, a: Mapping[str, tuple[float, Path | None]], b: Mapping[str, tuple[float, Path | None]]) -> bool:
    """Whether two truths' joints play the same (clearances to 0.1 um, worn surfaces by content)."""
    def key(j: str, c: float, w: Path | None) -> tuple[str, str]:
        return clearance_mark(bench.name, j, c), wear_mark(bench.name, j, None if w is None else file_digest(w))

    return set(a) == set(b) and all(key(j, *a[j]) == key(j, *b[j]) for j in a)


@dataclass(frozen=True)
class Faults:
    drop_rate: float = 0.0
    corrupt_rate: float = 0.0
    disconnect_after: float | None = None  # s after stream start
    stall_at: float | None = None
    bus_off_at: float | None = None
    bus_off_duration: float = 0.2
    reply_delay: float = 0.0  # s
    garbage_at: float | None = None
    garbage_bytes: int = 256
    freeze_at: float | None = None
    index_lost_at: float | None = None


@dataclass(frozen=True)
class EmulatorConfig:
    """Validated ``[emulator]`` table; ``table`` keeps the raw table (to hand to a subprocess)."""

    seed: int = 0
    signal: str = "model"
    revolutions: int = DEFAULT_REVOLUTIONS  # non-twin truth: whole revolutions played after settling
    settle: float = 2.0            # model revolutions simulated and dropped first (twin: then 1 kept)
    accel_block: int = 200         # samples per accelerometer block
    encoder_block: int = 10        # samples per encoder block
    buffer: float = 2.0            # s of samples the device holds before it overruns
    cache: bool = True             # keep model signal tables on disk
    accelerometer: Accelerometer = field(default_factory=Accelerometer)
    motor: MotorImperfections = field(default_factory=MotorImperfections)
    encoder: EncoderImperfections = field(default_factory=EncoderImperfections)
    truth: Truth = field(default_factory=Truth)
    faults: Faults = field(default_factory=Faults)
    table: Mapping[str, Any] = field(default_factory=dict, compare=False)

    def to_table(self) -> dict[str, Any]:
        """A raw ``[emulator]`` table (SI values with units) that :meth:`from_table` reads back equal."""
        a, m, e, t, f = self.accelerometer, self.motor, self.encoder, self.truth, self.faults
        faults: dict[str, Any] = {"drop_rate": f.drop_rate, "corrupt_rate": f.corrupt_rate,
                                  "bus_off_duration": f"{f.bus_off_duration!r} s",
                                  "reply_delay": f"{f.reply_delay!r} s", "garbage_bytes": f.garbage_bytes}
        for name in ("disconnect_after", "stall_at", "bus_off_at", "garbage_at", "freeze_at", "index_lost_at"):
            if getattr(f, name) is not None:
                faults[name] = f"{getattr(f, name)!r} s"
        return {
            "seed": self.seed, "signal": self.signal, "revolutions": self.revolutions, "settle": self.settle,
            "accel_block": self.accel_block, "encoder_block": self.encoder_block,
            "buffer": f"{self.buffer!r} s", "cache": self.cache,
            "accelerometer": {"noise": f"{a.noise!r} m/s^2", "bias": f"{a.bias!r} m/s^2",
                              "clipping": a.clipping, "adc_bits": a.adc_bits,
                              "drift": f"{a.drift * 1e6!r} ppm", "resonance": f"{a.resonance!r} Hz",
                              "damping": a.damping, "white_level": f"{a.white_level!r} m/s^2",
                              "aa_filter": a.aa_filter, "aa_order": a.aa_order, "aa_cutoff": a.aa_cutoff,
                              "sensitivity": a.sensitivity, "cross_axis": a.cross_axis,
                              "lateral_mode": f"{a.lateral_mode!r} Hz", "lateral_damping": a.lateral_damping,
                              **({"spread": {"mode": [f"{a.spread.mode[0]!r} Hz", f"{a.spread.mode[1]!r} Hz"],
                                             "damping": list(a.spread.damping),
                                             "sensitivity": a.spread.sensitivity,
                                             "cross_axis": list(a.spread.cross_axis),
                                             "lateral_mode": [f"{f!r} Hz" for f in a.spread.lateral_mode],
                                             "lateral_damping": list(a.spread.lateral_damping)}}
                                 if a.spread else {})},
            "motor": {"ripple": m.ripple, "ripple_harmonic": m.ripple_harmonic},
            "encoder": {"index": e.index, "index_angle": f"{e.index_angle!r} rad"},
            "truth": {"clearances": {j: f"{c!r} m" for j, c in t.clearances.items()},
                      "wear": {j: str(Path(p).resolve()) for j, p in t.wear.items()},
                      "wear_stage": t.wear_stage, "accel_delay": f"{t.accel_delay!r} s",
                      **({"twin": True} if t.seed is None else {"seed": t.seed})},
            "faults": faults,
        }

    @classmethod
    def from_bench(cls, bench: Bench) -> EmulatorConfig:
        """The bench file's ``[emulator]`` table, validated (errors name the bench file)."""
        return cls.from_table(bench.emulator, bench=bench)

    @classmethod
    def from_table(cls, table: Mapping[str, Any], *, bench: Bench | None = None,
                   source: str | Path | None = None) -> EmulatorConfig:
        """Validate a raw ``[emulator]`` table (as parsed from TOML or JSON)."""
        src = source or (bench.path if bench is not None and bench.path else getattr(bench, "name", "<emulator>"))
        r = TomlReader(src)
        data = r.table(dict(table) if isinstance(table, Mapping) else table, "emulator")
        sections = {"accelerometer", "motor", "encoder", "truth", "faults"}
        r.keys(data, "emulator", set(), {"seed", "signal", "revolutions", "settle", "accel_block",
                                         "encoder_block", "buffer", "cache"} | sections)
        for s in sections:
            r.table(data.get(s, {}), f"emulator.{s}")
        motor, truth = _motor(r, data.get("motor", {})), _truth(r, data.get("truth", {}), bench)
        accelerometer = _accelerometer(r, data.get("accelerometer", {}))
        if accelerometer.spread is not None and truth.seed is not None:
            accelerometer = accelerometer.spread.draw(accelerometer, truth.seed)
        _check_carriage(r, data.get("accelerometer", {}), accelerometer, bench)
        if truth.seed is not None and motor.ripple:
            raise r.fail("emulator.motor.ripple", data["motor"]["ripple"],
                         "expected 0 (or no ripple key) with [emulator.truth] seed: a drawn truth takes its "
                         "speed error and ripple from the bench's [tolerances] speed and ripple")
        return cls(
            seed=int(r.number(data, "emulator", "seed", low=0, default=0, integer=True)),
            signal=r.text(data, "emulator", "signal", choices=SIGNALS, default="model"),
            revolutions=int(r.number(data, "emulator", "revolutions", low=1, high=1000, default=DEFAULT_REVOLUTIONS,
                                     integer=True)),
            settle=r.number(data, "emulator", "settle", low=0.0, high=50.0, default=2.0),
            accel_block=int(r.number(data, "emulator", "accel_block", low=1, high=2000, default=200, integer=True)),
            encoder_block=int(r.number(data, "emulator", "encoder_block", low=1, high=1000, default=10,
                                       integer=True)),
            buffer=r.quantity(data, "emulator", "buffer", "time", positive=True, default=2.0),
            cache=_flag(r, data, "emulator", "cache", True),
            accelerometer=accelerometer,
            motor=motor,
            encoder=_encoder(r, data.get("encoder", {})),
            truth=truth,
            faults=_faults(r, data.get("faults", {})),
            table=dict(table),
        )


def _flag(r: TomlReader, data: dict, key: str, name: str, default: bool) -> bool:
    raw = data.get(name, default)
    if not isinstance(raw, bool):
        raise r.fail(f"{key}.{name}", raw, "expected true or false")
    return raw


def _accelerometer(r: TomlReader, d: dict) -> Accelerometer:
    k = "emulator.accelerometer"
    r.keys(d, k, set(), {"noise", "bias", "clipping", "adc_bits", "drift", "resonance", "damping", "white_level",
                         "aa_filter", "aa_order", "aa_cutoff", "sensitivity", "cross_axis", "lateral_mode",
                         "lateral_damping", "spread"})
    bits = d.get("adc_bits", 16)
    if bits is False:
        bits = 0
    d = {**d, "adc_bits": bits}
    drift = r.quantity(d, k, "drift", "drift", default=0.0)
    if abs(drift) > 1e-3:
        raise r.fail(f"{k}.drift", d["drift"], "expected a sample-clock drift within +/-1000 ppm")
    cross = r.number(d, k, "cross_axis", low=-_CROSS_AXIS_LIMIT, high=_CROSS_AXIS_LIMIT, default=0.0)
    lateral_mode = r.quantity(d, k, "lateral_mode", "frequency", nonnegative=True, default=0.0)
    if cross and not lateral_mode:
        raise r.fail(f"{k}.cross_axis", d["cross_axis"], "expected 0 without a lateral_mode (Hz): on a rigid "
                     "guide the carriage does not move sideways, so a cross-axis sensitivity sees nothing")
    return Accelerometer(
        noise=r.quantity(d, k, "noise", "acceleration", nonnegative=True, default=0.0),
        bias=r.quantity(d, k, "bias", "acceleration", default=0.0),
        clipping=_flag(r, d, k, "clipping", True),
        adc_bits=int(r.number(d, k, "adc_bits", low=0, high=16, default=16, integer=True)),
        drift=drift,
        resonance=r.quantity(d, k, "resonance", "frequency", nonnegative=True, default=0.0),
        damping=r.number(d, k, "damping", low=0.0, high=2.0, default=0.05, open_low=True),
        white_level=r.quantity(d, k, "white_level", "acceleration", nonnegative=True, default=10.0),
        aa_filter=r.text(d, k, "aa_filter", choices=AA_FILTERS, default="none"),
        aa_order=int(r.number(d, k, "aa_order", low=1, high=12, default=8, integer=True)),
        aa_cutoff=r.number(d, k, "aa_cutoff", low=0.0, high=0.5, default=0.3, open_low=True),
        sensitivity=r.number(d, k, "sensitivity", low=0.5, high=2.0, default=1.0),
        cross_axis=cross,
        lateral_mode=lateral_mode,
        lateral_damping=r.number(d, k, "lateral_damping", low=0.0, high=2.0, default=0.05, open_low=True),
        spread=_spread(r, d["spread"]) if "spread" in d else None,
    )


def _spread(r: TomlReader, d: Any) -> SensorSpread:
    k = "emulator.accelerometer.spread"
    r.keys(r.table(d, k), k, set(), {"mode", "damping", "sensitivity", "cross_axis", "lateral_mode",
                                     "lateral_damping"})

    def pair(name: str, default: tuple[float, float], read) -> tuple[float, float]:
        if name not in d:
            return default
        raw = d[name]
        if not isinstance(raw, list) or len(raw) != 2:
            raise r.fail(f"{k}.{name}", raw, "expected [low, high]")
        lo, hi = (read({name: v}) for v in raw)
        if not lo <= hi:
            raise r.fail(f"{k}.{name}", raw, "expected low <= high")
        return lo, hi

    base = SensorSpread()  # what an empty table draws
    mode = pair("mode", base.mode, lambda v: r.quantity(v, k, "mode", "frequency", positive=True))
    damping = pair("damping", base.damping, lambda v: r.number(v, k, "damping", low=0.0, high=2.0, open_low=True))
    cross = pair("cross_axis", base.cross_axis,
                 lambda v: r.number(v, k, "cross_axis", low=0.0, high=_CROSS_AXIS_LIMIT))
    lateral = pair("lateral_mode", base.lateral_mode,
                   lambda v: r.quantity(v, k, "lateral_mode", "frequency", positive=True))
    lateral_damping = pair("lateral_damping", base.lateral_damping,
                           lambda v: r.number(v, k, "lateral_damping", low=0.0, high=2.0, open_low=True))
    return SensorSpread(mode, damping, r.number(d, k, "sensitivity", low=0.0, high=0.5, default=base.sensitivity),
                        cross, lateral, lateral_damping)


def _check_carriage(r: TomlReader, d: dict, acc: Accelerometer, bench: Bench | None) -> None:
    """A cross-axis signal needs the lateral force on the sensor's body (``signal.lateral_force``)."""
    if not acc.lateral or bench is None:
        return
    if carriage(bench) is None:
        key, raw = (("spread.cross_axis", d["spread"].get("cross_axis", list(SensorSpread().cross_axis)))
                    if "spread" in d else ("cross_axis", d.get("cross_axis")))
        raise r.fail(f"emulator.accelerometer.{key}", raw,
                     "expected 0 ([0, 0] in a spread) on this bench: a cross-axis signal needs the accelerometer "
                     "on a body sliding on a prismatic guide fixed to the frame and joined to the rest by ideal pins")


def _motor(r: TomlReader, d: dict) -> MotorImperfections:
    k = "emulator.motor"
    r.keys(d, k, set(), {"ripple", "ripple_harmonic"})
    return MotorImperfections(
        ripple=r.number(d, k, "ripple", low=0.0, high=0.5, default=0.0),
        ripple_harmonic=int(r.number(d, k, "ripple_harmonic", low=1, high=64, default=1, integer=True)),
    )


def _encoder(r: TomlReader, d: dict) -> EncoderImperfections:
    k = "emulator.encoder"
    r.keys(d, k, set(), {"index", "index_angle"})
    return EncoderImperfections(index=_flag(r, d, k, "index", True),
                                index_angle=r.quantity(d, k, "index_angle", "angle", default=0.0))


def _truth(r: TomlReader, d: dict, bench: Bench | None) -> Truth:
    k = "emulator.truth"
    r.keys(d, k, set(), {"clearances", "wear", "wear_stage", "accel_delay", "seed", "twin", "state"})
    joints = {j.name: j for j in bench.clearance_joints} if bench is not None else None
    twin = _flag(r, d, k, "twin", "seed" not in d)
    if twin and "seed" in d:
        raise r.fail(f"{k}.twin", d["twin"], "expected twin = false or no twin key with a seed (a seed draws a "
                     "non-twin truth; twin = true plays the nominal model)")
    if not twin and "seed" not in d:
        raise r.fail(f"{k}.twin", d["twin"], "expected a seed with twin = false (the draw of the truth)")
    seed = None if twin else int(r.number(d, k, "seed", low=0, high=2**31 - 1, integer=True))
    if "state" in d:
        state = _named_state(r, d, k, bench)
        return Truth(dict(state.clearances), dict(state.surfaces), d.get("wear_stage", state.name),
                     r.quantity(d, k, "accel_delay", "time", nonnegative=True, default=0.0), seed)
    clearances: dict[str, float] = {}
    for name, raw in r.table(d.get("clearances", {}), f"{k}.clearances").items():
        if joints is not None and name not in joints:
            raise r.fail(f"{k}.clearances.{name}", raw, f"expected a clearance joint of the bench: {sorted(joints)}")
        c = r.quantity({name: raw}, f"{k}.clearances", name, "length", positive=True)
        if joints is not None and not c < joints[name].clearance.bearing_radius:
            raise r.fail(f"{k}.clearances.{name}", raw,
                         f"expected less than the bearing radius {joints[name].clearance.bearing_radius} m")
        clearances[name] = c
    base = bench.path.parent if bench is not None and bench.path else None
    wear: dict[str, Path] = {}
    for name, raw in r.table(d.get("wear", {}), f"{k}.wear").items():
        if joints is not None and name not in joints:
            raise r.fail(f"{k}.wear.{name}", raw, f"expected a clearance joint of the bench: {sorted(joints)}")
        if not isinstance(raw, str) or not raw:
            raise r.fail(f"{k}.wear.{name}", raw, "expected the path of a worn-surface .npz file")
        p = Path(raw) if base is None or Path(raw).is_absolute() else base / raw
        if not p.exists():
            raise r.fail(f"{k}.wear.{name}", raw, f"expected a saved worn-surface file; {p} does not exist")
        wear[name] = p
    stage = d.get("wear_stage", "")
    if not isinstance(stage, str):
        raise r.fail(f"{k}.wear_stage", stage, "expected text (a wear stage label)")
    return Truth(clearances, wear, stage, r.quantity(d, k, "accel_delay", "time", nonnegative=True, default=0.0),
                 seed)


def _named_state(r: TomlReader, d: dict, k: str, bench: Bench | None) -> WearState:
    """The bench's ``[[state]]`` named by ``truth.state`` (then clearances and wear come from it)."""
    raw = d["state"]
    if bench is None:
        raise r.fail(f"{k}.state", raw, "expected clearances and wear instead: no bench to look the state up in")
    names = [s.name for s in bench.states]
    if raw not in names:
        raise r.fail(f"{k}.state", raw, f"expected one of the bench's [[state]] names: {names}")
    for other in ("clearances", "wear"):
        if other in d:
            raise r.fail(f"{k}.{other}", d[other], f"expected no {other} with state = {raw!r} (the state sets them)")
    stage = d.get("wear_stage", raw)
    if not isinstance(stage, str):
        raise r.fail(f"{k}.wear_stage", stage, "expected text (a wear stage label)")
    return next(s for s in bench.states if s.name == raw)


def _faults(r: TomlReader, d: dict) -> Faults:
    k = "emulator.faults"
    r.keys(d, k, set(), {"drop_rate", "corrupt_rate", "disconnect_after", "stall_at", "bus_off_at",
                         "bus_off_duration", "reply_delay", "garbage_at", "garbage_bytes", "freeze_at",
                         "index_lost_at"})

    def when(name: str) -> float | None:
        return r.quantity(d, k, name, "time", nonnegative=True) if name in d else None

    return Faults(
        drop_rate=r.number(d, k, "drop_rate", low=0.0, high=1.0, default=0.0),
        corrupt_rate=r.number(d, k, "corrupt_rate", low=0.0, high=1.0, default=0.0),
        disconnect_after=when("disconnect_after"),
        stall_at=when("stall_at"),
        bus_off_at=when("bus_off_at"),
        bus_off_duration=r.quantity(d, k, "bus_off_duration", "time", positive=True, default=0.2),
        reply_delay=r.quantity(d, k, "reply_delay", "time", nonnegative=True, default=0.0),
        garbage_at=when("garbage_at"),
        garbage_bytes=int(r.number(d, k, "garbage_bytes", low=1, high=1 << 20, default=256, integer=True)),
        freeze_at=when("freeze_at"),
        index_lost_at=when("index_lost_at"),
    )


def emulator_config(bench: Bench, state: WearState | str | None = None, seed: int | None = None, *,
                    accelerometer: Mapping[str, Any] | None = None, table: Mapping[str, Any] | None = None,
                    noise_seed: int | None = None, **emulator: Any) -> EmulatorConfig:
    """The emulator config of ``bench`` whose truth is ``state`` drawn with ``seed``.

    Starts from ``table`` (default the bench's ``[emulator]`` table) and sets ``[emulator.truth]``:
    ``state`` a ``[[state]]`` name of the bench or a :class:`WearState` (None: the bench's own
    clearances, no wear), ``seed`` an int for a non-twin truth drawn from ``[tolerances]`` (then the
    table's ``[emulator.motor] ripple`` is dropped: the draw has its own) or None for the twin.
    The truth's ``accel_delay`` is kept. ``accelerometer`` updates keys of
    ``[emulator.accelerometer]`` (raw values with units, e.g. ``{"resonance": "25 kHz"}``);
    ``emulator`` sets top-level keys (``revolutions``, ``settle``, ``signal``, ``cache``, ...).
    ``noise_seed`` is the top-level ``[emulator] seed`` (the device's noise and fault draws);
    default: ``seed`` for a drawn truth (each truth its own noise), else the table's.
    Hand ``config.to_table()`` to the serial/CAN emulators or the sim backend's ``config`` option.
    """
    raw: dict[str, Any] = {k: (dict(v) if isinstance(v, Mapping) else v)
                           for k, v in (bench.emulator if table is None else table).items()}
    old = raw.get("truth", {})
    truth: dict[str, Any] = {"accel_delay": old["accel_delay"]} if "accel_delay" in old else {}
    if isinstance(state, str):
        truth["state"] = state
    elif state is not None:
        truth["clearances"] = {j: f"{c!r} m" for j, c in state.clearances.items()}
        truth["wear"] = {j: str(Path(p).resolve()) for j, p in state.surfaces.items()}
        truth["wear_stage"] = state.name
    if seed is None:
        truth["twin"] = True
    else:
        truth["seed"] = int(seed)
        raw["seed"] = int(seed)
        raw["motor"] = {k: v for k, v in raw.get("motor", {}).items() if k != "ripple"}
    raw["truth"] = truth
    if accelerometer:
        raw["accelerometer"] = {**raw.get("accelerometer", {}), **accelerometer}
    raw.update(emulator)
    if noise_seed is not None:
        raw["seed"] = int(noise_seed)
    return EmulatorConfig.from_table(raw, bench=bench)
