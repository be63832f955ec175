"""The accelerometer's delay behind the encoder as the lab states it (``[sensor.chain]`` of the bench).

A fit on the acceleration cannot place the sensor chain's delay to 0.2 ms: a bench's tolerances and
the chaos of its impacts shift its own curve by as much (``benchmarks/validation/delay_floor.py``). Labs know it
from the chain itself: the DAQ's anti-alias filter (type, order, cutoff; or its datasheet group
delay), the sensor's mounted resonance (its calibration sheet; or a stated delay), the rest (a tap
test) and the DAQ's sample-clock drift against the encoder's. From that statement this module
computes the chain's group delay in the band the windows are aligned in: the analogue prototype of
each stated filter, its group delay ``-d arg H(j w) / d w`` summed over its poles and zeros in
closed form, averaged over the band. Imports numpy, scipy and the bench schema.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal
from wearbench.bench.schema import SensorChainStatement

__all__ = ["StatedDelay", "analog_group_delay", "stated_delay", "stated_response"]


def analog_group_delay(z: np.ndarray, p: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Group delay (s) at frequencies ``f`` (Hz) of the analogue filter with zeros ``z`` and poles
    ``p`` (rad/s): for each root r = a + j b, d/dw arg(j w - r) = -a / (a^2 + (w - b)^2)."""
    w = 2 * np.pi * np.asarray(f, dtype=float)[..., None]

    def slope(roots: np.ndarray) -> np.ndarray:
        roots = np.asarray(roots, dtype=complex)
        if roots.size == 0:
            return np.zeros(w.shape[:-1])
        a, b = roots.real[None, :], roots.imag[None, :]
        return np.sum(-a / (a * a + (w - b) ** 2), axis=-1)

    return slope(p) - slope(z)


def _filter_zpk(chain: SensorChainStatement) -> tuple[np.ndarray, np.ndarray]:
    wc = 2 * np.pi * chain.filter_cutoff
    if chain.filter == "butterworth":
        z, p, _ = signal.butter(chain.filter_order, wc, analog=True, output="zpk")
    else:
        z, p, _ = signal.bessel(chain.filter_order, wc, norm="mag", analog=True, output="zpk")
    return z, p


def _resonance_poles(chain: SensorChainStatement) -> np.ndarray:
    wn, zeta = 2 * np.pi * chain.resonance, chain.damping
    return np.roots([1.0, 2 * zeta * wn, wn * wn])


@dataclass(frozen=True)
class StatedDelay:
    """The stated delay of the accelerometer behind the encoder: ``filter + sensor + latency`` (s)
    at the stream's start, growing by ``clock_drift`` per second of the stream; ``uncertainty`` (s)."""

    filter: float
    sensor: float
    latency: float
    clock_drift: float
    uncertainty: float
    band: tuple[float, float]  # Hz, where the group delays were averaged

    @property
    def constant(self) -> float:
        return self.filter + self.sensor + self.latency

    def at(self, since_start: float | np.ndarray) -> float | np.ndarray:
        """The delay (s) ``since_start`` s after the accelerometer stream began: a sample clock fast by
        ``clock_drift`` stamps its samples ever later than they were taken."""
        return self.constant + self.clock_drift / (1.0 + self.clock_drift) * np.asarray(since_start)

    def describe(self) -> str:
        drift = f" + {self.clock_drift * 1e6:g} ppm clock drift" if self.clock_drift else ""
        return (f"stated {self.constant * 1e3:.3f} ms (filter {self.filter * 1e3:.3f}, sensor {self.sensor * 1e3:.3f}, "
                f"latency {self.latency * 1e3:.3f} ms{drift}; +/- {self.uncertainty * 1e3:.3f} ms)")

    def to_dict(self) -> dict:
        return {"filter_s": self.filter, "sensor_s": self.sensor, "latency_s": self.latency,
                "clock_drift": self.clock_drift, "uncertainty_s": self.uncertainty, "band_hz": list(self.band)}


def stated_delay(chain: SensorChainStatement, band: tuple[float, float] = (1.0, 100.0)) -> StatedDelay:
    """The delay ``chain`` states, its filters' group delays averaged over ``band`` (Hz)."""
    f = np.linspace(band[0], band[1], 64)
    if chain.filter_delay is not None:
        filt = chain.filter_delay
    elif chain.filter != "none":
        filt = float(analog_group_delay(*_filter_zpk(chain), f).mean())
    else:
        filt = 0.0
    if chain.sensor_delay is not None:
        sensor = chain.sensor_delay
    elif chain.resonance:
        sensor = float(analog_group_delay(np.zeros(0), _resonance_poles(chain), f).mean())
    else:
        sensor = 0.0
    return StatedDelay(filt, sensor, chain.latency, chain.clock_drift, chain.uncertainty,
                       (float(band[0]), float(band[1])))


def stated_response(chain: SensorChainStatement, f: np.ndarray) -> np.ndarray:
    """The stated chain's complex frequency response at ``f`` (Hz): its anti-alias filter (or its
    datasheet delay as a pure delay), its mounted resonance (or its stated delay) and its latency;
    1 at 0 Hz. What a tap through this chain is predicted to look like (``validation/tap_test.py``)."""
    w = 2 * np.pi * np.asarray(f, dtype=float)
    h = np.exp(-1j * w * chain.latency)
    if chain.filter_delay is not None:
        h = h * np.exp(-1j * w * chain.filter_delay)
    elif chain.filter != "none":
        z, p = _filter_zpk(chain)
        h = h * _unit_dc(z, p, w)
    if chain.sensor_delay is not None:
        h = h * np.exp(-1j * w * chain.sensor_delay)
    elif chain.resonance:
        h = h * _unit_dc(np.zeros(0), _resonance_poles(chain), w)
    return h


def _unit_dc(z: np.ndarray, p: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Response at ``w`` (rad/s) of the analogue filter with zeros ``z`` and poles ``p``, gain 1 at 0 Hz."""
    s = 1j * np.asarray(w)[..., None]
    num = np.prod(s - z, axis=-1) if len(z) else 1.0
    num0 = np.prod(-z) if len(z) else 1.0
    return (num / num0) * (np.prod(-p) / np.prod(s - p, axis=-1))
