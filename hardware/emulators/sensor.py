"""The accelerometer's sensor chain, applied after the physics: what turns the slider's acceleration
into the numbers a DAQ delivers.

Order (each stage can be off): mounting resonance (second-order low-pass at ``resonance`` Hz with
damping ratio ``damping``, bilinear with pre-warping) -> anti-alias filter (Butterworth or Bessel
low-pass of ``aa_order`` at ``aa_cutoff`` x sample rate) -> sampling (keep every ``oversample``-th
sample of the internal rate) -> sensitivity error (a gain) -> bias -> white noise -> clipping at +/- range -> ADC quantisation.
The two filters run on the signal at the internal rate ``oversample x sample rate`` (see
:func:`oversampling`; 1 for a clean chain, which is plain point sampling), so what lies above the
sample rate's Nyquist frequency is attenuated as the analogue filter of a DAQ would, before it can
alias. Imports numpy, scipy and the emulator config.
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
    unless the mounting resonance lies above 0.4 x the sample rate, then enough for it (2.5 x its
    frequency): the resonance rings above Nyquist and aliases, as it would on a DAQ without an
    anti-alias filter. With one: enough for ``INTERNAL_RATE`` and for the resonance, at least 2."""
    need = 2.5 * acc.resonance
    if acc.aa_filter == "none":
        return 1 if acc.resonance < 0.4 * sample_rate else math.ceil(need / sample_rate - 1e-9)
    return max(2, math.ceil(max(INTERNAL_RATE, need) / sample_rate - 1e-9))


class SensorChain:
    """The chain for one (sample rate, range) configuration; stateful across calls (filter memory).

    :meth:`process` takes the physical signal at the internal rate (``oversample`` values per
    output sample, the last of each group at the output sample's instant) and returns the samples.
    """

    def __init__(self, acc: Accelerometer, sample_rate: float, range_m_s2: float, rng: np.random.Generator):
        self.acc = acc
        self.sample_rate = float(sample_rate)
        self.range = float(range_m_s2)
        self.oversample = oversampling(acc, self.sample_rate)
        self.internal_rate = self.sample_rate * self.oversample
        self._rng = rng
        self.clipped = 0  # samples at full scale so far (the ADC's extreme codes: what a host sees as clipped)
        sections = []
        fr = acc.resonance
        if fr:
            fs = self.internal_rate
            if fr >= _RESONANCE_LIMIT * fs:
                raise ValueError(f"mounting resonance {fr:g} Hz needs a sample rate above "
                                 f"{fr / _RESONANCE_LIMIT:g} Hz, the accelerometer samples at {fs:g} Hz")
            wn = 2 * fs * math.tan(math.pi * fr / fs)  # pre-warped so the peak lands at fr
            b, a = sps.bilinear([wn**2], [1.0, 2 * acc.damping * wn, wn**2], fs)
            sections.append(sps.tf2sos(b, a))
        if acc.aa_filter != "none":
            sections.append(anti_alias_sos(acc, self.sample_rate, self.internal_rate))
        self.sos = np.vstack(sections) if sections else None
        self._zi: np.ndarray | None = None

    def reset(self) -> None:
        """Forget the filter memory (a stream restarts or the device lost samples)."""
        self._zi = None

    def process(self, x: np.ndarray) -> np.ndarray:
        """Samples (float32 m/s^2, quantised if the ADC is on) from the internal-rate signal ``x``."""
        acc = self.acc
        if self.sos is not None:
            if self._zi is None:
                self._zi = sps.sosfilt_zi(self.sos) * x[0]
            x, self._zi = sps.sosfilt(self.sos, x, zi=self._zi)
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


def anti_alias_sos(acc: Accelerometer, sample_rate: float, internal_rate: float) -> np.ndarray:
    """Second-order sections of the anti-alias low-pass at the internal rate (digital, bilinear;
    Butterworth: -3 dB at the cutoff; Bessel: normalised to -3 dB at the cutoff too)."""
    cutoff = acc.aa_cutoff * sample_rate
    if acc.aa_filter == "butterworth":
        return sps.butter(acc.aa_order, cutoff, fs=internal_rate, output="sos")
    return sps.bessel(acc.aa_order, cutoff, norm="mag", fs=internal_rate, output="sos")
