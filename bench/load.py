"""Reading a bench file: TOML in, a validated :class:`~wearbench.bench.schema.Bench` out.

Every value is validated on load; a mistake raises :class:`~wearbench.bench.schema.BenchError`
naming the file, the key, the value and what was expected. Also: where the shipped bench files
are (``hardware/benches``, data of the far end of the cable) and the one resolver every command
uses to turn a name or a path into a bench file.
"""

from __future__ import annotations

import hashlib
import math
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from wearbench.bench.schema import (
    BACKENDS,
    CONTACT_LAWS,
    GROUND,
    STIFFNESS_FORMS,
    AnalysisTable,
    Bench,
    BenchError,
    Body,
    Clearance,
    ContactLaw,
    Driver,
    Frequency,
    Hardware,
    Joint,
    Material,
    Motor,
    Sensor,
    SensorChainStatement,
    Tolerances,
    WearSettings,
    WearState,
)
from wearbench.bench.units import QuantityError, parse_quantity

__all__ = ["BENCH_DIR", "TomlReader", "load_bench", "load_states", "parse_bench", "resolve_bench", "shipped_bench"]

# wearbench/bench/load.py -> wearbench/hardware/benches, installed or editable (folders = subpackages)
BENCH_DIR = Path(__file__).resolve().parents[1] / "hardware" / "benches"


class TomlReader:
    """Walks the parsed TOML with the file name at hand, so every error can name file and key."""

    def __init__(self, path: str | Path):
        self.path = path

    def fail(self, key: str, value: Any, expected: str) -> BenchError:
        return BenchError(self.path, key, value, expected)

    def table(self, data: Any, key: str) -> dict:
        if not isinstance(data, dict):
            raise self.fail(key, data, "expected a table")
        return data

    def keys(self, data: dict, key: str, required: set[str], optional: set[str] = frozenset()) -> None:
        allowed = required | set(optional)
        for k, v in data.items():
            if k not in allowed:
                raise self.fail(f"{key}.{k}" if key else k, v,
                                f"unknown key; expected one of {sorted(allowed)}")
        for k in sorted(required):
            if k not in data:
                raise self.fail(f"{key}.{k}" if key else k, None, "missing required key")

    def quantity(self, data: dict, key: str, name: str, dimension: str, *, positive: bool = False,
                 nonnegative: bool = False, default: float | None = None) -> float:
        if name not in data:
            if default is None:
                raise self.fail(f"{key}.{name}", None, f"missing required {dimension}")
            return default
        raw = data[name]
        try:
            value = parse_quantity(raw, dimension)
        except QuantityError as exc:
            raise self.fail(f"{key}.{name}", raw, str(exc)) from None
        if positive and not value > 0:
            raise self.fail(f"{key}.{name}", raw, f"expected a positive {dimension}")
        if nonnegative and value < 0:
            raise self.fail(f"{key}.{name}", raw, f"expected a non-negative {dimension}")
        return value

    def number(self, data: dict, key: str, name: str, *, low: float | None = None, high: float | None = None,
               default: float | None = None, integer: bool = False, open_low: bool = False) -> float:
        if name not in data:
            if default is None:
                raise self.fail(f"{key}.{name}", None, "missing required number")
            return default
        raw = data[name]
        if isinstance(raw, bool) or not isinstance(raw, (int, float)) or (integer and not isinstance(raw, int)):
            kind = "an integer" if integer else "a plain number (dimensionless)"
            raise self.fail(f"{key}.{name}", raw, f"expected {kind}")
        if not math.isfinite(raw):
            raise self.fail(f"{key}.{name}", raw, "expected a finite number")
        bad_low = low is not None and (raw <= low if open_low else raw < low)
        if bad_low or (high is not None and raw > high):
            lo = "(" if open_low else "["
            raise self.fail(f"{key}.{name}", raw, f"expected a number in {lo}{low}, {high}]")
        return raw

    def text(self, data: dict, key: str, name: str, *, choices: tuple[str, ...] | None = None,
             default: str | None = None) -> str:
        if name not in data:
            if default is None:
                raise self.fail(f"{key}.{name}", None, "missing required text")
            return default
        raw = data[name]
        if not isinstance(raw, str) or not raw:
            raise self.fail(f"{key}.{name}", raw, "expected non-empty text")
        if choices is not None and raw not in choices:
            raise self.fail(f"{key}.{name}", raw, f"expected one of {list(choices)}")
        return raw

    def point(self, raw: Any, key: str) -> tuple[float, float]:
        if not isinstance(raw, list) or len(raw) != 2:
            raise self.fail(key, raw, "expected a point [x, y] with units, e.g. ['0.1 m', '0 m']")
        try:
            return (parse_quantity(raw[0], "length"), parse_quantity(raw[1], "length"))
        except QuantityError as exc:
            raise self.fail(key, raw, str(exc)) from None

    def name_list(self, data: dict, key: str, name: str, length: int | None = None) -> tuple[str, ...]:
        raw = data.get(name)
        if not isinstance(raw, list) or not raw or not all(isinstance(x, str) and x for x in raw):
            raise self.fail(f"{key}.{name}", raw, "expected a list of names")
        if length is not None and len(raw) != length:
            raise self.fail(f"{key}.{name}", raw, f"expected {length} names")
        return tuple(raw)


def _contact(r: TomlReader, data: dict, key: str, base: ContactLaw) -> ContactLaw:
    fields = {"law", "stiffness", "restitution", "exponent", "friction_coefficient", "friction_v0", "friction_vm"}
    r.keys(data, key, set(), fields)
    v0 = r.quantity(data, key, "friction_v0", "speed", positive=True, default=base.friction_v0)
    vm = r.quantity(data, key, "friction_vm", "speed", positive=True, default=base.friction_vm)
    if not vm > v0:
        raise r.fail(f"{key}.friction_vm", data.get("friction_vm", vm), f"expected friction_vm > friction_v0 = {v0} m/s")
    return ContactLaw(
        law=r.text(data, key, "law", choices=CONTACT_LAWS, default=base.law),
        stiffness=r.text(data, key, "stiffness", choices=STIFFNESS_FORMS, default=base.stiffness),
        restitution=r.number(data, key, "restitution", low=0.0, high=1.0, default=base.restitution, open_low=True),
        exponent=r.number(data, key, "exponent", low=1.0, high=3.0, default=base.exponent),
        friction_coefficient=r.number(data, key, "friction_coefficient", low=0.0, high=2.0,
                                      default=base.friction_coefficient),
        friction_v0=v0,
        friction_vm=vm,
    )


def _material(r: TomlReader, name: str, data: dict) -> Material:
    key = f"materials.{name}"
    r.table(data, key)
    r.keys(data, key, {"youngs_modulus", "poisson_ratio", "hardness"}, {"density"})
    return Material(
        name=name,
        youngs_modulus=r.quantity(data, key, "youngs_modulus", "pressure", positive=True),
        poisson_ratio=r.number(data, key, "poisson_ratio", low=0.0, high=0.5, open_low=False),
        hardness=r.quantity(data, key, "hardness", "pressure", positive=True),
        density=r.quantity(data, key, "density", "density", positive=True) if "density" in data else None,
    )


def _body(r: TomlReader, i: int, data: dict) -> Body:
    key = f"body[{i}]"
    r.table(data, key)
    name = r.text(data, key, "name")
    key = f"body[{i}] ({name})"
    r.keys(data, key, {"name", "mass", "inertia"}, {"length", "points"})
    if name == GROUND:
        raise r.fail(f"{key}.name", name, f"'{GROUND}' is the ground; describe its points under [frame]")
    length = r.quantity(data, key, "length", "length", positive=True) if "length" in data else None
    points: dict[str, tuple[float, float]] = {}
    if length is not None:
        points = {"start": (-length / 2, 0.0), "end": (length / 2, 0.0)}
    for pname, raw in r.table(data.get("points", {}), f"{key}.points").items():
        if pname in points:
            raise r.fail(f"{key}.points.{pname}", raw, "this point is already defined by the bar's length")
        points[pname] = r.point(raw, f"{key}.points.{pname}")
    if not points:
        raise r.fail(f"{key}.points", None, "a body needs a length (a bar) or named points")
    return Body(
        name=name,
        mass=r.quantity(data, key, "mass", "mass", positive=True),
        inertia=r.quantity(data, key, "inertia", "inertia", positive=True),
        points=points,
        length=length,
    )


def _clearance(r: TomlReader, key: str, data: dict, bodies: tuple[str, ...], materials: dict[str, Material],
               contact: ContactLaw, base_dir: Path | None) -> Clearance:
    r.table(data, key)
    r.keys(data, key, {"bearing_body", "bearing_radius", "journal_radius", "bearing_material",
                       "journal_material", "axial_length"}, {"contact", "surfaces"})
    if len(bodies) != 2:
        raise r.fail(key, bodies, "a clearance joint connects exactly two bodies")
    bearing_body = r.text(data, key, "bearing_body", choices=bodies)
    journal_body = bodies[1] if bearing_body == bodies[0] else bodies[0]
    r1 = r.quantity(data, key, "bearing_radius", "length", positive=True)
    r2 = r.quantity(data, key, "journal_radius", "length", positive=True)
    if not r2 < r1:
        raise r.fail(f"{key}.journal_radius", data["journal_radius"],
                     f"expected a journal smaller than its bearing (bearing radius {r1 * 1e3:g} mm)")
    mats = {}
    for side in ("bearing_material", "journal_material"):
        mname = r.text(data, key, side)
        if mname not in materials:
            raise r.fail(f"{key}.{side}", mname, f"expected a material defined under [materials]: {sorted(materials)}")
        mats[side] = materials[mname]
    surfaces = None
    if "surfaces" in data:
        raw = r.text(data, key, "surfaces")
        surfaces = Path(raw) if base_dir is None else (base_dir / raw)
        if not surfaces.exists():
            raise r.fail(f"{key}.surfaces", raw, f"expected a saved worn-surface file; {surfaces} does not exist")
    return Clearance(
        bearing_body=bearing_body,
        journal_body=journal_body,
        bearing_radius=r1,
        journal_radius=r2,
        bearing_material=mats["bearing_material"],
        journal_material=mats["journal_material"],
        axial_length=r.quantity(data, key, "axial_length", "length", positive=True),
        contact=_contact(r, r.table(data.get("contact", {}), f"{key}.contact"), f"{key}.contact", contact),
        surfaces=surfaces,
    )


def _joint(r: TomlReader, i: int, data: dict, bodies: dict[str, Body], ground: dict, materials: dict,
           contact: ContactLaw, base_dir: Path | None) -> Joint:
    key = f"joint[{i}]"
    r.table(data, key)
    name = r.text(data, key, "name")
    key = f"joint[{i}] ({name})"
    r.keys(data, key, {"name", "type", "bodies", "points"}, {"axis", "clearance"})
    kind = r.text(data, key, "type", choices=("revolute", "prismatic"))
    names = r.name_list(data, key, "bodies")
    pts = r.name_list(data, key, "points", len(names))
    if len(names) < 2 or (kind == "prismatic" and len(names) != 2):
        raise r.fail(f"{key}.bodies", list(names), "expected two bodies (a revolute pin may join more)")
    if len(set(names)) != len(names):
        raise r.fail(f"{key}.bodies", list(names), "expected distinct bodies")
    for b, p in zip(names, pts):
        if b == GROUND:
            known = ground
        elif b in bodies:
            known = bodies[b].points
        else:
            raise r.fail(f"{key}.bodies", b, f"expected '{GROUND}' or a body: {sorted(bodies)}")
        if p not in known:
            raise r.fail(f"{key}.points", p, f"expected a point of {b}: {sorted(known)}")
    axis = None
    if kind == "prismatic":
        axis = r.quantity(data, key, "axis", "angle")
    elif "axis" in data:
        raise r.fail(f"{key}.axis", data["axis"], "only a prismatic joint has an axis")
    clearance = None
    if "clearance" in data:
        if kind != "revolute":
            raise r.fail(f"{key}.clearance", data["clearance"], "only a revolute joint can have clearance")
        clearance = _clearance(r, f"{key}.clearance", data["clearance"], names, materials, contact, base_dir)
    return Joint(name=name, kind=kind, bodies=names, points=pts, axis=axis, clearance=clearance)


def _sensor(r: TomlReader, i: int, data: dict, bodies: dict[str, Body], joints: dict[str, Joint]) -> Sensor:
    key = f"sensor[{i}]"
    r.table(data, key)
    kind = r.text(data, key, "kind", choices=("accelerometer", "encoder"))
    if kind == "accelerometer":
        r.keys(data, key, {"name", "kind", "body", "point", "axis", "range", "sample_rate"}, {"sensitivity", "chain"})
        body = r.text(data, key, "body", choices=tuple(bodies))
        point = r.text(data, key, "point", choices=tuple(bodies[body].points))
        return Sensor(
            name=r.text(data, key, "name"), kind=kind, body=body, point=point,
            axis=r.quantity(data, key, "axis", "angle"),
            range=r.quantity(data, key, "range", "acceleration", positive=True),
            sample_rate=r.quantity(data, key, "sample_rate", "frequency", positive=True),
            sensitivity=(r.quantity(data, key, "sensitivity", "sensitivity", positive=True)
                         if "sensitivity" in data else None),
            chain=_chain(r, f"{key}.chain", data["chain"]) if "chain" in data else None,
        )
    r.keys(data, key, {"name", "kind", "joint", "counts_per_rev", "sample_rate"})
    joint = r.text(data, key, "joint", choices=tuple(j for j, v in joints.items() if v.kind == "revolute"))
    return Sensor(
        name=r.text(data, key, "name"), kind=kind, joint=joint,
        counts_per_rev=int(r.number(data, key, "counts_per_rev", low=1, integer=True)),
        sample_rate=r.quantity(data, key, "sample_rate", "frequency", positive=True),
    )


def _sensors(r: TomlReader, raw: Any, bodies: dict[str, Body], joints: dict[str, Joint],
             drivers: tuple[Driver, ...]) -> tuple[Sensor, ...]:
    """``[[sensor]]`` tables: every sensor is one wearbench uses, or it is refused here (never ignored).

    wearbench records and analyses one accelerometer and one encoder, and the encoder counts the turns
    of a driven crank (what the recorder, the emulator and the analysis read as the crank angle)."""
    if not isinstance(raw, list):
        raise r.fail("sensor", raw, "expected an array of tables [[sensor]]")
    sensors: list[Sensor] = []
    driven = [d.joint for d in drivers]
    for i, item in enumerate(raw):
        s = _sensor(r, i, item, bodies, joints)
        key = f"sensor[{i}] ({s.name})"
        if any(o.name == s.name for o in sensors):
            raise r.fail(f"{key}.name", s.name, "expected a unique sensor name")
        first = next((k for k, o in enumerate(sensors) if o.kind == s.kind), None)
        if first is not None:
            used = f"sensor[{first}] ({sensors[first].name})"
            what = ("one acceleration stream is recorded and analysed" if s.kind == "accelerometer"
                    else "one encoder gives the crank angle")
            raise r.fail(f"{key}.kind", s.kind, f"expected one {s.kind} per bench: {used} is the one wearbench "
                         f"uses ({what}) and it cannot use a second; remove this one, or describe it in a copy "
                         "of the bench file")
        if s.kind == "encoder" and s.joint not in driven:
            raise r.fail(f"{key}.joint", s.joint, f"expected a driven joint, one of the [[driver]] joints {driven}: "
                         "the encoder gives the driven crank's angle (the recorder counts cycles by it, the "
                         "analysis addresses the signal by it)")
        sensors.append(s)
    return tuple(sensors)


def _either(r: TomlReader, data: dict, key: str, stated: str, parts: tuple[str, ...]) -> None:
    """A chain stage is stated either by its response (``parts``) or by its delay (``stated``)."""
    if stated in data and any(p in data for p in parts):
        raise r.fail(f"{key}.{stated}", data[stated], f"expected either {stated} or {'/'.join(parts)}, not both "
                     "(the stage's stated delay, or its response from which the host computes the delay)")


def _chain(r: TomlReader, key: str, data: Any) -> SensorChainStatement:
    """``[sensor.chain]``: what the lab states of the accelerometer's chain (bench.schema.SensorChainStatement)."""
    r.table(data, key)
    r.keys(data, key, {"uncertainty"}, {"filter", "filter_order", "filter_cutoff", "filter_delay", "resonance",
                                        "damping", "sensor_delay", "latency", "clock_drift"})
    _either(r, data, key, "filter_delay", ("filter", "filter_order", "filter_cutoff"))
    _either(r, data, key, "sensor_delay", ("resonance", "damping"))
    kind = r.text(data, key, "filter", choices=("butterworth", "bessel", "none"), default="none")
    order, cutoff = 0, 0.0
    if kind != "none":
        order = int(r.number(data, key, "filter_order", low=1, high=16, integer=True))
        cutoff = r.quantity(data, key, "filter_cutoff", "frequency", positive=True)
    else:
        for k in ("filter_order", "filter_cutoff"):
            if k in data:
                raise r.fail(f"{key}.{k}", data[k], "expected a filter type with it (filter = 'butterworth' | 'bessel')")
    resonance = r.quantity(data, key, "resonance", "frequency", positive=True, default=0.0)
    if "damping" in data and not resonance:
        raise r.fail(f"{key}.damping", data["damping"], "expected a resonance with it (resonance = '25 kHz')")
    drift = r.quantity(data, key, "clock_drift", "drift", default=0.0)
    if abs(drift) > 1e-3:
        raise r.fail(f"{key}.clock_drift", data["clock_drift"], "expected a sample-clock drift within +/-1000 ppm")
    return SensorChainStatement(
        filter=kind, filter_order=order, filter_cutoff=cutoff,
        filter_delay=r.quantity(data, key, "filter_delay", "time", nonnegative=True) if "filter_delay" in data else None,
        resonance=resonance, damping=r.number(data, key, "damping", low=0.0, high=1.0, open_low=True, default=0.05),
        sensor_delay=r.quantity(data, key, "sensor_delay", "time", nonnegative=True) if "sensor_delay" in data else None,
        latency=r.quantity(data, key, "latency", "time", default=0.0), clock_drift=drift,
        uncertainty=r.quantity(data, key, "uncertainty", "time", nonnegative=True))


def _hardware(r: TomlReader, data: dict) -> Hardware:
    r.table(data, "hardware")
    r.keys(data, "hardware", {"backend"}, set(BACKENDS))
    backend = r.text(data, "hardware", "backend", choices=BACKENDS)
    options = {name: r.table(data[name], f"hardware.{name}") for name in BACKENDS if name in data}
    return Hardware(backend=backend, options=options)


_TOP = {"bench", "operating", "motor", "materials", "contact", "wear", "frame", "body", "joint", "driver",
        "assembly", "sensor", "hardware", "emulator", "tolerances", "state", "compute", "analysis"}

_RELATIVE = {"mass", "inertia", "friction", "restitution", "exponent", "speed", "ripple", "start"}


def _tolerances(r: TomlReader, data: dict) -> Tolerances:
    key = "tolerances"
    r.keys(data, key, set(), _RELATIVE | {"length", "ground"})
    d = Tolerances()
    values = {name: float(r.number(data, key, name, low=0.0, high=1.0, default=getattr(d, name)))
              for name in _RELATIVE}
    for name in ("length", "ground"):
        values[name] = r.quantity(data, key, name, "length", nonnegative=True, default=getattr(d, name))
    return Tolerances(**values)


def _frequency(r: TomlReader, key: str, raw: Any) -> Frequency:
    """A frequency of ``[analysis]``: a plain number is crank orders, a quantity ("50 Hz") fixed hertz."""
    if isinstance(raw, bool) or not isinstance(raw, (int, float, str)):
        raise r.fail(key, raw, "expected crank orders (a number, e.g. 50) or a frequency (e.g. '50 Hz')")
    if isinstance(raw, str):
        try:
            value = parse_quantity(raw, "frequency")
        except QuantityError as exc:
            raise r.fail(key, raw, f"{exc}; or crank orders as a plain number, e.g. 50") from None
        orders = False
    else:
        value, orders = float(raw), True
    if not (math.isfinite(value) and value > 0):
        raise r.fail(key, raw, "expected a positive number of crank orders or a positive frequency")
    return Frequency(value, orders)


def _analysis(r: TomlReader, data: dict) -> AnalysisTable:
    """``[analysis]``: how the analysis scales with this bench (``bench.schema.AnalysisTable``)."""
    key = "analysis"
    r.keys(data, key, set(), {"bins", "lowpass", "lowpass_max", "bands", "window_lowpass", "speeds"})
    bins = int(r.number(data, key, "bins", low=4, high=360, integer=True)) if "bins" in data else None
    one = {name: _frequency(r, f"{key}.{name}", data[name]) if name in data else None
           for name in ("lowpass", "lowpass_max", "window_lowpass")}
    bands = None
    if "bands" in data:
        raw = data["bands"]
        if not isinstance(raw, list) or not raw:
            raise r.fail(f"{key}.bands", raw, "expected a list of [low, high] bands, e.g. [[50, 150], [150, 400]] "
                         "(crank orders) or [['50 Hz', '150 Hz']]")
        out = []
        for i, band in enumerate(raw):
            if not isinstance(band, list) or len(band) != 2:
                raise r.fail(f"{key}.bands[{i}]", band, "expected [low, high]")
            lo, hi = (_frequency(r, f"{key}.bands[{i}]", v) for v in band)
            if lo.orders != hi.orders or not lo.value < hi.value:
                raise r.fail(f"{key}.bands[{i}]", band, "expected low < high, both crank orders or both frequencies")
            out.append((lo, hi))
        bands = tuple(out)
    speeds = None
    if "speeds" in data:
        raw = data["speeds"]
        if not isinstance(raw, list) or len(raw) != 2:
            raise r.fail(f"{key}.speeds", raw, "expected the crank speeds [lowest, highest] the analysis is "
                         "validated for, e.g. ['60 rpm', '5000 rpm']")
        try:
            lo, hi = (abs(parse_quantity(v, "angular_speed")) for v in raw)
        except QuantityError as exc:
            raise r.fail(f"{key}.speeds", raw, str(exc)) from None
        if not 0 < lo <= hi or not math.isfinite(hi):
            raise r.fail(f"{key}.speeds", raw, "expected 0 < lowest <= highest crank speed")
        speeds = (lo, hi)
    return AnalysisTable(bins=bins, bands=bands, speeds=speeds, **one)


def _compute(r: TomlReader, data: dict) -> str | None:
    """``[compute] scheduler``: "local" or a Dask scheduler address ("tcp://10.0.0.5:8786")."""
    r.keys(data, "compute", set(), {"scheduler"})
    if "scheduler" not in data:
        return None
    value = data["scheduler"]
    if not isinstance(value, str) or not (value.strip().lower() == "local" or "://" in value):
        raise r.fail("compute.scheduler", value, "expected 'local' or a Dask scheduler address such as "
                     "'tcp://10.0.0.5:8786'")
    return value.strip()


def _states(r: TomlReader, raw: Any, joints: Mapping[str, Joint], base_dir: Path | None,
                key: str = "state") -> tuple[WearState, ...]:
    """Parse ``[[state]]`` tables: name, clearances {joint = length}, wear {joint = "new" | file.npz}."""
    if not isinstance(raw, list):
        raise r.fail(key, raw, "expected an array of tables [[state]]")
    clear = {n: j for n, j in joints.items() if j.clearance is not None}
    states: list[WearState] = []
    for i, item in enumerate(raw):
        k = f"{key}[{i}]"
        r.table(item, k)
        r.keys(item, k, {"name"}, {"clearances", "wear"})
        name = r.text(item, k, "name")
        if any(s.name == name for s in states):
            raise r.fail(f"{k}.name", name, "expected a unique state name")
        clearances: dict[str, float] = {}
        for jname, value in r.table(item.get("clearances", {}), f"{k}.clearances").items():
            if jname not in clear:
                raise r.fail(f"{k}.clearances.{jname}", value, f"expected a clearance joint: {sorted(clear)}")
            c = r.quantity({jname: value}, f"{k}.clearances", jname, "length", positive=True)
            if not c < clear[jname].clearance.bearing_radius:
                raise r.fail(f"{k}.clearances.{jname}", value,
                             f"expected less than the bearing radius {clear[jname].clearance.bearing_radius} m")
            clearances[jname] = c
        surfaces: dict[str, Path] = {}
        for jname, value in r.table(item.get("wear", {}), f"{k}.wear").items():
            if jname not in clear:
                raise r.fail(f"{k}.wear.{jname}", value, f"expected a clearance joint: {sorted(clear)}")
            if not isinstance(value, str) or not value:
                raise r.fail(f"{k}.wear.{jname}", value, 'expected "new" or the path of a worn-surface .npz file')
            if value == "new":
                continue
            p = Path(value) if base_dir is None or Path(value).is_absolute() else base_dir / value
            if not p.is_file():
                raise r.fail(f"{k}.wear.{jname}", value, f"expected a saved worn-surface file; {p} does not exist")
            surfaces[jname] = p
        states.append(WearState(name, clearances, surfaces))
    return tuple(states)


def parse_bench(text: str, path: str | Path = "<bench>") -> Bench:
    """Read a bench from TOML ``text``; ``path`` names it in errors and anchors relative file names."""
    r = TomlReader(path)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise r.fail("(syntax)", None, f"not valid TOML: {exc}") from None
    r.keys(data, "", {"bench", "body", "joint", "driver"}, _TOP)
    base_dir = Path(path).parent if str(path) != "<bench>" else None

    head = r.table(data["bench"], "bench")
    r.keys(head, "bench", {"name"}, {"description"})

    op = r.table(data.get("operating", {}), "operating")
    r.keys(op, "operating", {"speed"}, {"gravity"})
    speed = r.quantity(op, "operating", "speed", "angular_speed")
    gravity_raw = op.get("gravity", ["0 m/s^2", "0 m/s^2"])
    if not isinstance(gravity_raw, list) or len(gravity_raw) != 2:
        raise r.fail("operating.gravity", gravity_raw, "expected [gx, gy] with units, e.g. ['0 m/s^2', '-9.81 m/s^2']")
    try:
        gravity = tuple(parse_quantity(g, "acceleration") for g in gravity_raw)
    except QuantityError as exc:
        raise r.fail("operating.gravity", gravity_raw, str(exc)) from None

    motor_raw = r.table(data.get("motor", {}), "motor")
    r.keys(motor_raw, "motor", set(), {"max_speed", "max_acceleration"})
    motor = Motor(
        max_speed=r.quantity(motor_raw, "motor", "max_speed", "angular_speed", positive=True, default=Motor.max_speed),
        max_acceleration=r.quantity(motor_raw, "motor", "max_acceleration", "angular_acceleration",
                                    positive=True, default=Motor.max_acceleration),
    )
    if abs(speed) > motor.max_speed:
        raise r.fail("operating.speed", op["speed"], f"expected at most the motor's max_speed {motor.max_speed:.4g} rad/s")

    materials = {n: _material(r, n, m) for n, m in r.table(data.get("materials", {}), "materials").items()}
    contact = _contact(r, r.table(data.get("contact", {}), "contact"), "contact", ContactLaw())

    wear_raw = r.table(data.get("wear", {}), "wear")
    r.keys(wear_raw, "wear", set(), {"coefficient", "regions", "cycles_per_stage", "stage_scale", "split"})
    d = WearSettings()
    wear = WearSettings(
        coefficient=r.quantity(wear_raw, "wear", "coefficient", "wear_coefficient", nonnegative=True,
                               default=d.coefficient),
        regions=int(r.number(wear_raw, "wear", "regions", low=8, integer=True, default=d.regions)),
        cycles_per_stage=int(r.number(wear_raw, "wear", "cycles_per_stage", low=1, integer=True,
                                      default=d.cycles_per_stage)),
        stage_scale=float(r.number(wear_raw, "wear", "stage_scale", low=1.0, default=d.stage_scale)),
        split=float(r.number(wear_raw, "wear", "split", low=0.0, high=1.0, default=d.split)),
    )

    frame = r.table(data.get("frame", {}), "frame")
    r.keys(frame, "frame", {"points"})
    ground = {p: r.point(v, f"frame.points.{p}") for p, v in r.table(frame["points"], "frame.points").items()}

    body_list = data["body"]
    if not isinstance(body_list, list):
        raise r.fail("body", body_list, "expected an array of tables [[body]]")
    bodies: dict[str, Body] = {}
    for i, raw in enumerate(body_list):
        b = _body(r, i, raw)
        if b.name in bodies:
            raise r.fail(f"body[{i}].name", b.name, "expected a unique body name")
        bodies[b.name] = b

    joint_list = data["joint"]
    if not isinstance(joint_list, list):
        raise r.fail("joint", joint_list, "expected an array of tables [[joint]]")
    joints: dict[str, Joint] = {}
    for i, raw in enumerate(joint_list):
        j = _joint(r, i, raw, bodies, ground, materials, contact, base_dir)
        if j.name in joints:
            raise r.fail(f"joint[{i}].name", j.name, "expected a unique joint name")
        joints[j.name] = j

    drivers = []
    for i, raw in enumerate(data["driver"] if isinstance(data["driver"], list) else [data["driver"]]):
        key = f"driver[{i}]"
        r.table(raw, key)
        r.keys(raw, key, {"joint", "phase"}, {"ratio"})
        jname = r.text(raw, key, "joint", choices=tuple(joints))
        if joints[jname].kind != "revolute" or GROUND not in joints[jname].bodies:
            raise r.fail(f"{key}.joint", jname, "expected a revolute joint to the frame (a crank pivot)")
        if joints[jname].clearance is not None:
            raise r.fail(f"{key}.joint", jname, "a driven pivot cannot have clearance")
        drivers.append(Driver(joint=jname, ratio=float(r.number(raw, key, "ratio", default=1.0)),
                              phase=r.quantity(raw, key, "phase", "angle")))
    if len({d.joint for d in drivers}) != len(drivers):
        raise r.fail("driver", [d.joint for d in drivers], "expected each driven joint once")

    assembly_raw = r.table(data.get("assembly", {}), "assembly")
    assembly = {}
    for jname, raw in assembly_raw.items():
        if jname not in joints:
            raise r.fail(f"assembly.{jname}", raw, f"expected a joint name: {sorted(joints)}")
        assembly[jname] = r.point(raw, f"assembly.{jname}")

    sensors = _sensors(r, data.get("sensor", []), bodies, joints, tuple(drivers))
    hardware = _hardware(r, data.get("hardware", {"backend": "sim"}))
    emulator = r.table(data.get("emulator", {}), "emulator")
    tolerances = _tolerances(r, r.table(data.get("tolerances", {}), "tolerances"))
    states = _states(r, data.get("state", []), joints, base_dir)
    scheduler = _compute(r, r.table(data.get("compute", {}), "compute"))
    analysis = _analysis(r, r.table(data.get("analysis", {}), "analysis"))

    return Bench(
        name=r.text(head, "bench", "name"),
        description=head.get("description", ""),
        path=Path(path) if base_dir is not None else None,
        source=text,
        sha256=hashlib.sha256(text.encode()).hexdigest(),
        speed=speed,
        gravity=gravity,
        ground_points=ground,
        bodies=tuple(bodies.values()),
        joints=tuple(joints.values()),
        drivers=tuple(drivers),
        sensors=sensors,
        materials=materials,
        contact=contact,
        wear=wear,
        motor=motor,
        hardware=hardware,
        assembly=assembly,
        emulator=emulator,
        tolerances=tolerances,
        states=states,
        scheduler=scheduler,
        analysis=analysis,
    )


def load_states(path: str | Path, bench: Bench) -> tuple[WearState, ...]:
    """Candidate states from a TOML file of ``[[state]]`` tables (as in a bench file) for ``bench``."""
    path = Path(path)
    r = TomlReader(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise BenchError(path, "(file)", None, f"cannot read the states file: {exc.strerror}") from None
    except UnicodeDecodeError:
        raise BenchError(path, "(file)", None, "not a text file; expected a TOML file of [[state]] tables") from None
    except tomllib.TOMLDecodeError as exc:
        raise r.fail("(syntax)", None, f"not valid TOML: {exc}") from None
    r.keys(data, "", {"state"})
    return _states(r, data["state"], {j.name: j for j in bench.joints}, path.parent)


def load_bench(path: str | Path) -> Bench:
    """Read and validate the bench file at ``path`` (see the shipped files in ``BENCH_DIR``)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise BenchError(path, "(file)", None, f"cannot read the bench file: {exc.strerror}") from None
    except UnicodeDecodeError:
        raise BenchError(path, "(file)", None, "not a text file; expected a bench file (TOML)") from None
    return parse_bench(text, path)


def shipped_bench(name: str) -> Path:
    """Path of a bench file shipped with wearbench, by name ("ninebar", "slider-crank", ...)."""
    path = BENCH_DIR / f"{name}.toml"
    if not path.exists():
        known = sorted(p.stem for p in BENCH_DIR.glob("*.toml"))
        raise FileNotFoundError(f"no shipped bench {name!r}; shipped: {known}")
    return path


def resolve_bench(text: str | Path) -> Path:
    """The bench file ``text`` names: a path to a file, or the name of a shipped bench
    ("ninebar-testbed", with or without ".toml"). Every command that takes a bench uses this.
    Raises FileNotFoundError naming what was tried and the shipped benches."""
    path = Path(text)
    if path.is_file():
        return path
    shipped = BENCH_DIR / f"{path.name.removesuffix('.toml')}.toml"
    if path.parent == Path(".") and shipped.is_file():
        return shipped
    known = sorted(p.stem for p in BENCH_DIR.glob("*.toml"))
    raise FileNotFoundError(f"{text}: no such bench file, and no shipped bench of that name; "
                            f"shipped: {', '.join(known)}")
