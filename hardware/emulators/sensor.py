"""The accelerometer's sensor chain, applied after the physics: what turns the acceleration of the sensor's point
into the numbers a DAQ delivers.

Order (each stage can be off): mounting resonance (second-order low-pass at ``resonance`` Hz with
damping ratio ``damping``, bilinear with pre-warping) -> plus the cross-axis part (below) -> anti-alias filter (Butterworth or Bessel
low-pass of ``aa_order`` at ``aa_cutoff`` x sample rate) -> sampling (keep every ``oversample``-th
sample of the internal rate) -> sensitivity error (a gain) -> bias -> white noise -> clipping at +/- range -> ADC quantisation.
The two filters run on the signal at the internal rate ``oversample x sample rate`` (see
:func:`oversampling`; 1 for a clean chain, which is plain point sampling), so what lies above the
sample rate's Nyquist frequency is attenuated as the analogue filter of a DAQ would, before it can
alias.

Cross-axis (``cross_axis`` and ``lateral_mode`` both set, else off and the chain is as before): the
carriage sits on its guide with a lateral stiffness and damping, a mode at ``lateral_mode`` Hz with
damping ratio ``lateral_damping`` whose mass is the sensor's body (the slider carriage). Driven by
the lateral force f of the signal table over that mass (``a_f = f/m``, m/s^2), its lateral
acceleration is ``a_lat = H(s) a_f`` with ``H(s) = s^2 / (s^2 + 2 zeta w s + w^2)`` (from
``m x'' + c x' + k x = f``: below the mode the guide holds the carriage, above it the carriage
moves with the force; bilinear with the peak pre-warped). The sensor adds ``cross_axis x a_lat`` to
its axial signal after the mounting resonance (which is the axial path) and before the DAQ's filter.
The lateral motion does not feed back into the mechanism (micrometres against millimetre clearances).
Imports numpy, scipy and the emulator config.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import signal as sps
from wearbench.hardware.emulators.config import Accelerometer
from wearbench.hardware.protocol.messages import counts_to_m_s2

__all__ = ["INTERNAL_RATE", "SensorChain", "oversampling"]

INTERNAL_RATE = 40000.0  # Hz: the internal rate is at least this (or 2.5 x the resonance) with an AA filter
_RESONANCE_LIMIT = 0.45  # the mounting resonance must lie below this fraction of the filter's rate


def oversampling(acc: Accelerometer, sample_rate: float) -> int:
    """Internal samples per output sample. Without an anti-alias filter: 1 (plain point sampling)
    unless the mounting resonance (or the lateral mode, with cross-axis) lies above 0.4 x the sample
    rate, then enough for it (2.5 x its frequency): the resonance rings above Nyquist and aliases, as
    it would on a DAQ without an anti-alias filter. With one: enough for ``INTERNAL_RATE`` and for the
    resonance, at least 2."""
    top = max(acc.resonance, acc.lateral_mode if acc.lateral else 0.0)
    need = 2.5 * top
    if acc.aa_filter == "none":
        return 1 if top < 0.4 * sample_rate else math.ceil(need / sample_rate - 1e-9)
    return max(2, math.ceil(max(INTERNAL_RATE, need) / sample_rate - 1e-9))


class SensorChain:
    """The chain for one (sample rate, range) configuration; stateful across calls (filter memory).

    :meth:`process` takes the physical signal at the internal rate (``oversample`` values per
    output sample, the last of each group at the output sample's instant), with cross-axis on also the
    lateral force over the carriage's mass at the same instants, and returns the samples.
    """

    def __init__(self, acc: Accelerometer, sample_rate: float, range_m_s2: float, rng: np.random.Generator):
        self.acc = acc
        self.sample_rate = float(sample_rate)
        self.range = float(range_m_s2)
        self.oversample = oversampling(acc, self.sample_rate)
        self.internal_rate = self.sample_rate * self.oversample
        self._rng = rng
        self.clipped = 0  # samples at full scale so far (the ADC's extreme codes: what a host sees as clipped)
        fs = self.internal_rate
        mount = [mode_sos(acc.resonance, acc.damping, fs, "mounting resonance")] if acc.resonance else []
        aa = [anti_alias_sos(acc, self.sample_rate, fs)] if acc.aa_filter != "none" else []
        self._axial = _Filter(mount + aa)  # the axial path as one cascade
        self.sos = self._axial.sos
        self.lateral = acc.lateral
        if self.lateral:  # the cross-axis part joins between the mount and the DAQ filter: three filters
            self._stages = (_Filter(mount), _Filter([mode_sos(acc.lateral_mode, acc.lateral_damping, fs,
                                                              "lateral carriage mode", highpass=True)]), _Filter(aa))

    def reset(self) -> None:
        """Forget the filter memory (a stream restarts or the device lost samples)."""
        for stage in (self._axial, *(self._stages if self.lateral else ())):
            stage.zi = None

    def process(self, x: np.ndarray, lateral: np.ndarray | None = None) -> np.ndarray:
        """Samples (float32 m/s^2, quantised if the ADC is on) from the internal-rate signal ``x`` (and,
        with cross-axis on, the lateral force over the carriage's mass ``lateral``, m/s^2)."""
        acc = self.acc
        if self.lateral:
            if lateral is None or np.shape(lateral) != np.shape(x):
                raise ValueError("sensor chain with cross-axis on: the lateral force over the carriage's mass is "
                                 f"needed at every internal instant ({np.size(x)} values)")
            mount, carriage, aa = self._stages
            x = aa(mount(x) + acc.cross_axis * carriage(np.asarray(lateral, dtype=float)))
        else:
            x = self._axial(x)
        x = acc.sensitivity * x[self.oversample - 1::self.oversample] + acc.bias
        if acc.noise:
            x = x + self._rng.normal(0.0, acc.noise, x.size)
        if acc.clipping:
            x = np.clip(x, -self.range, self.range)
        if acc.adc_bits:
            half = 2 ** (acc.adc_bits - 1)
            lsb = self.range / half
            counts = np.rint(x / lsb)
            if acc.clipping:
                counts = np.clip(counts, -half, half - 1)
                self.clipped += int(np.count_nonzero((counts >= half - 1) | (counts <= -half)))
            return counts_to_m_s2(counts * 2 ** (16 - acc.adc_bits), self.range / 32768.0)
        if acc.clipping:
            self.clipped += int(np.count_nonzero(np.abs(x) >= self.range))
        return x.astype(np.float32)


class _Filter:
    """A cascade of second-order sections with its memory (None: pass-through), started at steady state."""

    def __init__(self, sections: list[np.ndarray]):
        self.sos = np.vstack(sections) if sections else None
        self.zi: np.ndarray | None = None

    def __call__(self, x: np.ndarray) -> np.ndarray:
        if self.sos is None:
            return x
        if self.zi is None:
            self.zi = sps.sosfilt_zi(self.sos) * x[0]
        y, self.zi = sps.sosfilt(self.sos, x, zi=self.zi)
        return y


def mode_sos(frequency: float, damping: float, fs: float, name: str, *, highpass: bool = False) -> np.ndarray:
    """A second-order mode at ``frequency`` Hz, damping ratio ``damping``, at rate ``fs`` (bilinear, pre-warped
    so the peak lands at ``frequency``): the base-to-mass low-pass w^2/(s^2 + 2 zeta w s + w^2) of a mount, or
    (``highpass``) the force-to-acceleration s^2/(s^2 + 2 zeta w s + w^2) of a mass on a spring."""
    if frequency >= _RESONANCE_LIMIT * fs:
        raise ValueError(f"{name} {frequency:g} Hz needs a sample rate above {frequency / _RESONANCE_LIMIT:g} Hz, "
                         f"the accelerometer samples at {fs:g} Hz")
    wn = 2 * fs * math.tan(math.pi * frequency / fs)
    b, a = sps.bilinear([1.0, 0.0, 0.0] if highpass else [wn**2], [1.0, 2 * damping * wn, wn**2], fs)
    return sps.tf2sos(b, a)


def anti_alias_sos(acc: Accelerometer, sample_rate: float, internal_rate: float) -> np.ndarray:
    """Second-order sections of the anti-alias low-pass at the internal rate (digital, bilinear;
    Butterworth: -3 dB at the cutoff; Bessel: normalised to -3 dB at the cutoff too)."""
    cutoff = acc.aa_cutoff * sample_rate
    if acc.aa_filter == "butterworth":
        return sps.butter(acc.aa_order, cutoff, fs=internal_rate, output="sos")
    return sps.bessel(acc.aa_order, cutoff, norm="mag", fs=internal_rate, output="sos")
