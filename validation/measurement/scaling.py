"""The analysis in the bench's own terms: what the features, the kept curves and the windows look at,
resolved for one bench at one crank speed.

A crank cycle's acceleration holds two kinds of content. The kinematics and the slow dynamics are
harmonics of the crank: they move with its speed. Impacts in the clearance joints ring at frequencies
their contact sets, whatever the speed. And the sensor chain (sample rate, anti-alias filter, mounted
resonance) caps what can be seen at all. So the analysis is stated in crank orders (multiples of the
encoder crank's frequency ``f``) and resolved here, per bench and speed, into hertz (:func:`resolve_analysis`):

- **Curve** (the features' first block): low-passed at 50 crank orders, at most 1 kHz. Below 50 orders
  lie the kinematic harmonics; above about 1 kHz the curve would follow single impacts (their response
  lasts a millisecond or less in steel pins) and take on their chaos. At 5000 rpm 50 orders are
  4.2 kHz, which resolves single impacts.
- **Impact bands**: 50-150, 150-400 and 400-1000 crank orders. From 50 orders up the kinematic harmonics
  have died out, and a band-pass from there rings for about a fiftieth of a revolution, inside one 20
  degree bin, so a band's energy keeps its crank angle at any speed. Each band is cut at the sensor
  chain's cap and left out when less than 1.5:1 of it is left; when no band is left the features cannot
  see impacts at that speed and resolving refuses, saying so.
- **Cap**: the highest frequency the accelerometer's chain passes unchanged as the bench file states it:
  0.45 x its sample rate, 0.7 x its stated anti-alias filter's cut-off (where that filter is still
  flat), a fifth of its stated mounted resonance (within 5 %), the lowest of those given.
- **Model output rate**: 20 x the top band's upper edge, at least 20 kHz. The drawn mount of each
  realisation (``inference.sensor_path.PathSpread.around``) lies around the top band, so the rate
  leaves room above it.
- **Kept curves** (bands and window scores): CFC 180 scaled to the crank, class 180 ``f`` (the J211 class
  where that is one, else the Butterworth of the same design, order 2 per pass at 2.0775 x the class),
  its design frequency at most the cap.
- **Windows**: their slow curves (delay fit, ISO/TS 18571 of the low-passed window) at 10 crank orders,
  at most the curve's low-pass; the delay search's step and floor in crank periods
  (``comparison.windows.WindowOptions.for_crank``).

At the test bed's 1 Hz every value is the one its shipped theory was built with (50 Hz, 50-150, 150-400 and
400-1000 Hz, 20 kHz, CFC 180, 10 Hz), so its shipped ensembles and estimator stay current.

A bench's ``[analysis]`` table overrides each rule (``bench.schema.AnalysisTable``): ``bins``,
``lowpass``, ``lowpass_max``, ``bands`` and ``window_lowpass`` as crank orders (a plain number) or fixed
frequencies (``"50 Hz"``), and ``speeds``, the crank speeds the analysis is validated for on that bench.
Without it, the validated speeds are wearbench's own (:data:`VALIDATED_SPEEDS`: the shipped benches'
identification measured at 1, 1.5, 2 and 83.3 Hz cranks); a session outside them gets a note, not a
refusal.

Imports the bench schema and the features' spec.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from wearbench.bench.schema import AnalysisTable, Bench, Frequency
from wearbench.validation.measurement.features import FeatureSpec
from wearbench.validation.measurement.filters import CFC_CLASSES, CFC_DESIGN_FACTOR

__all__ = ["DEFAULT_ANALYSIS", "VALIDATED_SPEEDS", "Analysis", "crank_frequency", "hertz", "resolve_analysis",
           "sensor_cap"]

TWO_PI = 2.0 * math.pi
# the default rules in crank orders (``Frequency(value)``) and fixed hertz (``Frequency(value, False)``)
DEFAULT_ANALYSIS = AnalysisTable(
    bins=18, lowpass=Frequency(50.0), lowpass_max=Frequency(1000.0, orders=False),
    bands=((Frequency(50.0), Frequency(150.0)), (Frequency(150.0), Frequency(400.0)),
           (Frequency(400.0), Frequency(1000.0))),
    window_lowpass=Frequency(10.0))
# crank speeds (Hz) the default rules are validated at: the shipped benches' emulated sessions, the
# test bed and the four-bar at 1 Hz, a lab's four-bar at 1.5 Hz, the slider-crank at 120 and 5000 rpm
VALIDATED_SPEEDS = (1.0, 5000.0 / 60.0)
MIN_BAND_RATIO = 1.5  # a band cut at the cap shorter than this (high / low) is left out
OUTPUT_RATE = 20_000.0  # Hz, the model's output rate at least
OUTPUT_PER_TOP = 20.0  # ... and this times the top band's upper edge
CURVE_CFC = 180.0  # the kept curves' CFC class at a 1 Hz crank
FILTER_FLAT = 0.7  # an anti-alias filter passes flat up to this x its cut-off (8th order: -0.01 dB)
RESONANCE_FLAT = 5.0  # a mounted accelerometer reads within 5 % up to its resonance / this


def crank_frequency(bench: Bench | None, speed: float) -> float:
    """The encoder crank's frequency (Hz, > 0) at commanded motor ``speed`` (rad/s)."""
    ratio = bench.encoder_driver.ratio if bench is not None else 1.0
    f = abs(float(speed) * (ratio or 1.0)) / TWO_PI
    if not (math.isfinite(f) and f > 0):
        raise ValueError(f"analysis: motor speed {speed} rad/s: expected a turning crank (a finite speed other than 0)")
    return f


def sensor_cap(bench: Bench | None) -> tuple[float, str]:
    """The highest frequency (Hz) the bench's accelerometer chain passes unchanged as its file states
    it, and why: the lowest of 0.45 x the sample rate, 0.7 x the stated anti-alias filter's cut-off
    (where it is still flat: a band reaching into its roll-off loses a level that varies with crank
    angle, as impacts' spectra do) and a fifth of the stated mounted resonance (within 5 %); infinite
    without an accelerometer."""
    if bench is None:
        return math.inf, "no bench file"
    try:
        acc = bench.sensor("accelerometer")
    except KeyError:
        return math.inf, "no accelerometer"
    found = [(0.45 * acc.sample_rate, f"0.45 x the {acc.name} sample rate {hertz(acc.sample_rate)}")]
    chain = acc.chain
    if chain is not None:
        if chain.filter != "none" and chain.filter_cutoff > 0:
            found.append((FILTER_FLAT * chain.filter_cutoff,
                          f"{FILTER_FLAT:g} x the stated anti-alias filter's cut-off {hertz(chain.filter_cutoff)}"))
        if chain.resonance > 0:
            found.append((chain.resonance / RESONANCE_FLAT,
                          f"a fifth of the stated mounted resonance {hertz(chain.resonance)}"))
    return min(found)


@dataclass(frozen=True)
class Analysis:
    """The analysis of one bench at one crank speed, in hertz (see the module docstring)."""

    crank_hz: float
    features: FeatureSpec
    curve_filter: str  # the kept curves' filter (``filters.parse_filter`` text)
    output_rate: float  # Hz, the model's output grid
    window_lowpass: float  # Hz
    cap: float  # Hz, what the sensor chain passes
    cap_source: str
    speeds: tuple[float, float]  # crank Hz the analysis is validated for
    speeds_source: str
    left_out: tuple[str, ...] = ()  # bands cut or left out at the cap, in words

    @property
    def validated(self) -> bool:
        lo, hi = self.speeds
        return lo * (1 - 1e-6) <= self.crank_hz <= hi * (1 + 1e-6)

    def speed_note(self) -> str | None:
        """A note when the crank speed lies outside the validated speeds (None inside)."""
        if self.validated:
            return None
        lo, hi = self.speeds
        return (f"crank speed {self.crank_hz * 60:.4g} rpm lies outside the {lo * 60:.4g}-{hi * 60:.4g} rpm the "
                f"analysis is validated for ({self.speeds_source}): treat the result with care")

    def describe(self) -> list[str]:
        """The resolved analysis in words (``wearbench bench check``)."""
        s = self.features
        bands = ", ".join(f"{hertz(lo)}-{hertz(hi)}" for lo, hi in s.bands)
        head = (f"analysis at a {self.crank_hz:.4g} Hz crank ({self.crank_hz * 60:.4g} rpm): {s.bins} crank-angle bins, "
                f"curve low-passed at {hertz(s.lowpass)}, impact bands {bands}, kept curves {self.curve_filter}, "
                f"model output {hertz(self.output_rate)}, windows' slow curves {hertz(self.window_lowpass)}")
        lines = [head, f"sensor chain passes up to {hertz(self.cap)} ({self.cap_source})"]
        lines += [f"impact band {text}" for text in self.left_out]
        lo, hi = self.speeds
        lines.append(f"validated for crank speeds {lo * 60:.4g}-{hi * 60:.4g} rpm ({self.speeds_source})"
                     + ("" if self.validated else f": {self.crank_hz * 60:.4g} rpm lies outside"))
        return lines


def hertz(x: float) -> str:
    """A frequency as people write it: ``833 Hz``, ``12.5 kHz``."""
    return f"{x / 1000:.4g} kHz" if x >= 1000 else f"{x:.4g} Hz"


def _band_text(lo: Frequency, hi: Frequency) -> str:
    if lo.orders == hi.orders:
        return f"{lo.value:g}-{hi.value:g} {'crank orders' if lo.orders else 'Hz'}"
    return f"{lo.describe()} to {hi.describe()}"


def _pick(table: AnalysisTable, name: str):
    value = getattr(table, name)
    return getattr(DEFAULT_ANALYSIS, name) if value is None else value


def _curve_filter(crank_hz: float, cap: float) -> str:
    cfc = CURVE_CFC * crank_hz
    design = CFC_DESIGN_FACTOR * cfc
    if design > cap:
        return f"butter:{cap:.6g}:2"
    if abs(cfc - round(cfc)) < 1e-9 and round(cfc) in CFC_CLASSES:
        return f"cfc{round(cfc)}"
    return f"butter:{design:.6g}:2"


def resolve_analysis(bench: Bench | None, speed: float | None = None) -> Analysis:
    """The analysis of ``bench``'s sessions at commanded motor ``speed`` (rad/s; default the bench's):
    its ``[analysis]`` table's values where it has them, the default rules elsewhere. Raises ValueError
    (naming the bench, the speed and the sensor's cap) when no impact band fits below the cap."""
    speed = bench.speed if speed is None else speed
    f = crank_frequency(bench, speed)
    table = bench.analysis if bench is not None else AnalysisTable()
    where = f"{bench.name}: " if bench is not None else ""
    cap, cap_source = sensor_cap(bench)
    bands, left_out = [], []
    for lo_f, hi_f in _pick(table, "bands"):
        lo, full = lo_f.hz(f), hi_f.hz(f)
        hi = min(full, cap)
        if hi < MIN_BAND_RATIO * lo:
            left_out.append(f"{_band_text(lo_f, hi_f)} ({hertz(lo)}-{hertz(full)}) left out: above {hertz(cap)}")
            continue
        if hi < full:
            left_out.append(f"{_band_text(lo_f, hi_f)} cut at {hertz(cap)} (from {hertz(full)})")
        bands.append((lo, hi))
    if not bands:
        raise ValueError(f"{where}at a {f:.4g} Hz crank ({f * 60:.4g} rpm) every impact band lies above what the "
                         f"accelerometer's chain passes, {hertz(cap)} ({cap_source}): the features cannot see impacts "
                         "at this speed; expected a faster sample rate, or [analysis] bands below it")
    lowpass = min(_pick(table, "lowpass").hz(f), _pick(table, "lowpass_max").hz(f), cap)
    spec = FeatureSpec(bins=_pick(table, "bins"), lowpass=lowpass, bands=tuple(bands))
    top = max(hi for _, hi in bands)
    if table.speeds is not None:
        speeds = (table.speeds[0] / TWO_PI, table.speeds[1] / TWO_PI)
        source = "the bench file's [analysis] speeds"
    else:
        speeds, source = VALIDATED_SPEEDS, "wearbench's default analysis"
    return Analysis(f, spec, _curve_filter(f, cap), max(OUTPUT_RATE, OUTPUT_PER_TOP * top),
                    min(_pick(table, "window_lowpass").hz(f), lowpass), cap, cap_source, speeds, source,
                    tuple(left_out))
