"""Zero-phase filters for test and theory signals: SAE J211 CFC classes and Butterworth low-pass.

Holds the filter choice (``FilterSpec``, parsed from ``"cfc180"``, ``"butter:200:4"``, ``"none"``),
the J211-1 (rev. 2014, appendix C) digital CFC filter, its design response, and ``apply_filter``.
The same spec must go on both signals of a comparison. Pure numpy/scipy; imports nothing from
wearbench.

CFC filter (J211-1 appendix C): a two-pole Butterworth run forward and backward (four poles, no
phase), with ``wd = 2 pi CFC 2.0775``, ``wa = tan(wd T / 2)``,
``a0 = wa^2 / (1 + sqrt2 wa + wa^2)``, ``a1 = 2 a0``, ``a2 = a0``,
``b1 = -2 (wa^2 - 1) / (1 + sqrt2 wa + wa^2)``, ``b2 = (-1 + sqrt2 wa - wa^2) / (1 + sqrt2 wa + wa^2)``,
``y[n] = a0 x[n] + a1 x[n-1] + a2 x[n-2] + b1 y[n-1] + b2 y[n-2]``.
Its forward-backward gain is ``|H(f)|^2 = 1 / (1 + (tan(pi f T) / wa)^4)`` (``cfc_gain``).

Ends: both ends are padded by odd reflection (J211 asks for pre-/post-data; scipy's ``filtfilt``
``padtype="odd"`` with steady-state initial conditions) over ``PAD_PERIODS`` periods of the cut-off
frequency, so a window cut from the interior of a filtered record is unaffected by the record's ends.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal

__all__ = ["CFC_CLASSES", "FilterSpec", "apply_filter", "cfc_coefficients", "cfc_gain", "pad_length",
           "parse_filter"]

CFC_CLASSES = (60, 180, 600, 1000)
CFC_DESIGN_FACTOR = 2.0775  # J211-1 appendix C: single-pass design frequency / CFC
PAD_PERIODS = 10.0  # end padding, in periods of the filter's cut-off frequency


@dataclass(frozen=True)
class FilterSpec:
    """A zero-phase filter plus optional pre-processing, applied identically to test and theory.

    kind: "none" | "cfc" | "butter". cfc: channel frequency class (60, 180, 600, 1000).
    cutoff: Butterworth design cut-off (Hz; the zero-phase result is -6 dB there), order: its order
    (per pass). detrend: remove a least-squares line; remove_bias: subtract the mean (sensor bias;
    over whole cycles the slider acceleration averages to zero).
    """

    kind: str = "cfc"
    cfc: int = 180
    cutoff: float = 0.0
    order: int = 4
    detrend: bool = False
    remove_bias: bool = True

    @property
    def label(self) -> str:
        if self.kind == "cfc":
            return f"SAE J211 CFC {self.cfc}"
        if self.kind == "butter":
            return f"Butterworth low-pass {self.cutoff:g} Hz, order {self.order} (zero-phase)"
        return "unfiltered"

    @property
    def corner(self) -> float | None:
        """The frequency (Hz) that sets the end padding, or None for no filter."""
        if self.kind == "cfc":
            return CFC_DESIGN_FACTOR * self.cfc
        if self.kind == "butter":
            return self.cutoff
        return None


def parse_filter(text: str, *, detrend: bool = False, remove_bias: bool = True) -> FilterSpec:
    """``"cfc60"|"cfc180"|"cfc600"|"cfc1000"``, ``"butter:CUTOFF_HZ[:ORDER]"`` or ``"none"``."""
    t = text.strip().lower()
    common = {"detrend": detrend, "remove_bias": remove_bias}
    if t == "none":
        return FilterSpec(kind="none", **common)
    if t.startswith("cfc"):
        try:
            cfc = int(t[3:])
        except ValueError:
            cfc = -1
        if cfc not in CFC_CLASSES:
            raise ValueError(f"filter {text!r}: expected one of {', '.join(f'cfc{c}' for c in CFC_CLASSES)}")
        return FilterSpec(kind="cfc", cfc=cfc, **common)
    if t.startswith("butter"):
        parts = t.split(":")
        try:
            cutoff = float(parts[1])
            order = int(parts[2]) if len(parts) > 2 else 4
        except (IndexError, ValueError):
            raise ValueError(f"filter {text!r}: expected butter:CUTOFF_HZ[:ORDER], e.g. butter:200:4") from None
        if cutoff <= 0 or not 1 <= order <= 10 or len(parts) > 3:
            raise ValueError(f"filter {text!r}: expected cut-off > 0 Hz and order 1..10")
        return FilterSpec(kind="butter", cutoff=cutoff, order=order, **common)
    raise ValueError(f"filter {text!r}: expected cfc60|cfc180|cfc600|cfc1000, butter:CUTOFF_HZ[:ORDER] or none")


def cfc_coefficients(cfc: float, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """J211 single-pass coefficients as scipy ``(b, a)``: ``b = [a0, a1, a2]``, ``a = [1, -b1, -b2]``."""
    wd = 2.0 * np.pi * cfc * CFC_DESIGN_FACTOR
    wa = np.tan(wd / fs / 2.0)
    d = 1.0 + np.sqrt(2.0) * wa + wa * wa
    a0 = wa * wa / d
    b1 = -2.0 * (wa * wa - 1.0) / d
    b2 = (-1.0 + np.sqrt(2.0) * wa - wa * wa) / d
    return np.array([a0, 2.0 * a0, a0]), np.array([1.0, -b1, -b2])


def cfc_gain(f: np.ndarray | float, cfc: float, fs: float) -> np.ndarray:
    """Design amplitude gain of the forward-backward CFC filter at frequency ``f`` (Hz)."""
    wa = np.tan(np.pi * cfc * CFC_DESIGN_FACTOR / fs)
    return 1.0 / (1.0 + (np.tan(np.pi * np.asarray(f, dtype=float) / fs) / wa) ** 4)


def pad_length(spec: FilterSpec, fs: float) -> int:
    """Samples of end padding (and of the margin a window needs around it) for ``spec`` at ``fs``."""
    corner = spec.corner
    return 0 if corner is None else int(np.ceil(PAD_PERIODS * fs / corner))


def apply_filter(x: np.ndarray, fs: float, spec: FilterSpec) -> np.ndarray:
    """Bias/trend removal then the zero-phase filter of ``spec`` on samples ``x`` at ``fs`` Hz."""
    y = np.asarray(x, dtype=float)
    if y.ndim != 1 or y.size < 3:
        raise ValueError(f"filter: expected a 1-D signal of at least 3 samples, got shape {y.shape}")
    if not np.all(np.isfinite(y)):
        raise ValueError(f"filter: signal has {int(np.sum(~np.isfinite(y)))} non-finite samples")
    if spec.detrend:
        y = signal.detrend(y, type="linear")
    elif spec.remove_bias:
        y = y - y.mean()
    pad = min(pad_length(spec, fs), y.size - 1)
    if spec.kind == "cfc":
        if spec.cfc * CFC_DESIGN_FACTOR >= fs / 2:
            raise ValueError(f"filter CFC {spec.cfc}: needs a sample rate above {2 * CFC_DESIGN_FACTOR * spec.cfc:.0f} Hz, "
                             f"got {fs:g} Hz")
        b, a = cfc_coefficients(spec.cfc, fs)
        return signal.filtfilt(b, a, y, padtype="odd", padlen=pad)
    if spec.kind == "butter":
        if spec.cutoff >= fs / 2:
            raise ValueError(f"filter Butterworth {spec.cutoff:g} Hz: above the Nyquist frequency {fs / 2:g} Hz")
        sos = signal.butter(spec.order, spec.cutoff, fs=fs, output="sos")
        return signal.sosfiltfilt(sos, y, padtype="odd", padlen=pad)
    return y
