"""The window part of the report: each session's five-cycle windows against every state's ensemble.

Figures for a paper (its Figs. 36-39 set a measured curve beside a simulated one, impacts and all):
per state, the measured window, one realisation's window of that state (the one with the median
ISO/TS 18571 rating against it), the ensemble's 5-95 % band and the residual against the band (how
far outside it the measurement lies, 0 inside), by time and by crank angle; and the states side by
side. Tables: every window's verdict, delay, statistics and ISO/TS 18571 sub-scores. Matplotlib
object API (no pyplot); imports validation.windows for types.
"""

from __future__ import annotations

import html
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from wearbench.validation.comparison.windows import SessionWindows, WindowVerdict

__all__ = ["NOTES", "window_figure", "window_section", "window_table", "windows_side_by_side"]

NOTES = (
    ("Windows: each five-cycle window of steady cycles (cut at crank angle 0 of the encoder, CFC 180, "
     "0.5 deg crank-angle grid) is compared with the ensemble's own five-cycle windows of each state, "
     "impacts included, aligned by the encoder's crank angle. The accelerometer's delay behind the encoder "
     "(the sensor chain) is the bench's statement ([sensor.chain]: the DAQ filter's and the sensor's group delay, "
     "the latency, the clock drift since the stream began) plus one fitted residual per session within the "
     "statement's uncertainty, reported as 'stated X ms + fitted residual Y ms' (a residual at its bound is "
     "flagged); without a statement it is fitted from the signal alone, once per session within 0 to max_delay, "
     "and a fit on the acceleration scatters by about the floor named with it (benchmarks/validation/delay_floor.py)."),
    ("Window verdict: consistent when the window's cycle features (low-passed curve and impact energies in "
     "20 deg bins, as the identification uses them) are no more likely under the best other candidate, "
     "relative to the state, than the same windows of held-out realisations are (the generalised likelihood "
     "ratio), at the stated false-alarm rate alpha (the empirical p-value among the held-out windows; chosen "
     "on fresh truths, README 'How sessions are scored'). It is one-sided: a window unlike every candidate "
     "but toward none is the identification's consistency test's to catch; the distances in all features and "
     "along the candidates are in scores.json. An inconsistent window departs at the crank angles where a feature of the window "
     "lies beyond the Bonferroni limit of the state's spread, or where more of it is outside the band than "
     "in any held-out realisation window. ISO/TS 18571 is reported against single realisations (mean rating and "
     "sub-scores) with the ratings of held-out realisations against the same ones as reference; it does "
     "not decide (measured in README 'How sessions are scored')."),
)


def _outside(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Residual against the band: how far ``x`` lies above ``hi`` or below ``lo`` (0 inside)."""
    return np.where(x > hi, x - hi, np.where(x < lo, x - lo, 0.0))


def window_figure(w: WindowVerdict, band: tuple[np.ndarray, np.ndarray, np.ndarray], title: str, path: Path,
                  save: Callable[[Figure, Path], Path]) -> Path:
    """Measured window, one realisation, band and residual against the band, by time and by angle."""
    lo, _, hi = band
    realisation = w.realisation_window
    n, grid = w.measured.shape
    deg = np.arange(grid) * 360.0 / grid
    rea = realisation.reshape(n, grid)
    fig = Figure(figsize=(12, 6.4))
    axes = fig.subplots(2, 2, sharex="col", gridspec_kw={"height_ratios": [3, 1.3], "width_ratios": [1.6, 1]})
    t = w.times.ravel()
    lo_t, hi_t = np.tile(lo, n), np.tile(hi, n)
    ax = axes[0, 0]
    ax.fill_between(t, lo_t, hi_t, color="tab:red", alpha=0.2, lw=0, label=f"{w.state}: 5-95 % band")
    ax.plot(t, rea.ravel(), color="tab:red", lw=0.6, label=f"realisation #{w.realisation}")
    ax.plot(t, w.measured.ravel(), color="black", lw=0.6, label="measured")
    ax.set_ylabel("acceleration, kept curves' filter (m/s$^2$)")
    ax.legend(loc="upper right", fontsize=8)
    axes[1, 0].plot(t, _outside(w.measured, lo, hi).ravel(), color="tab:blue", lw=0.6)
    axes[1, 0].set_ylabel("outside band (m/s$^2$)")
    axes[1, 0].set_xlabel(f"time from window start (s; accelerometer read {w.delay_s * 1e3:.2f} ms late)")
    ax = axes[0, 1]
    ax.fill_between(deg, lo, hi, color="tab:red", alpha=0.2, lw=0)
    for k in range(n):
        ax.plot(deg, rea[k], color="tab:red", lw=0.4, alpha=0.6)
        ax.plot(deg, w.measured[k], color="black", lw=0.4, alpha=0.6)
    res = _outside(w.measured, lo, hi)
    for k in range(n):
        axes[1, 1].plot(deg, res[k], color="tab:blue", lw=0.4, alpha=0.7)
    axes[1, 1].set_xlim(0, 360)
    axes[1, 1].set_xlabel("crank angle (deg)")
    verdict = "consistent" if w.consistent else "inconsistent"
    fig.suptitle(f"{title}: cycles {w.start_cycle}-{w.start_cycle + n - 1} against {w.state}: {verdict} "
                 f"(p {w.p:.3f}), "
                 f"ISO R {w.iso['rating']:.3f} vs realisations", fontsize=10)
    return save(fig, path)


def windows_side_by_side(title: str, windows: Mapping[str, SessionWindows], path: Path,
                         save: Callable[[Figure, Path], Path]) -> Path:
    """The session's first window against every state, one row per state, by time."""
    states = [s for s in windows if windows[s].windows]
    fig = Figure(figsize=(12, 2.2 * len(states) + 0.8))
    axes = np.atleast_1d(fig.subplots(len(states), 1, sharex=True, sharey=True))
    for ax, s in zip(axes, states, strict=True):
        w = windows[s].windows[0]
        lo, _, hi = windows[s].band
        n = w.measured.shape[0]
        t = w.times.ravel()
        ax.fill_between(t, np.tile(lo, n), np.tile(hi, n), color="tab:red", alpha=0.2, lw=0)
        ax.plot(t, w.realisation_window, color="tab:red", lw=0.5)
        ax.plot(t, w.measured.ravel(), color="black", lw=0.5)
        ax.set_title(f"{s}: {'consistent' if w.consistent else 'inconsistent'}, delay {w.delay_s * 1e3:.2f} ms",
                     fontsize=9, loc="left")
        ax.set_ylabel("m/s$^2$")
    axes[-1].set_xlabel("time from window start (s)")
    fig.suptitle(f"{title}: the first window (black) against each state's band and one realisation (red)",
                 fontsize=10)
    return save(fig, path)


def window_table(session: str, windows: Mapping[str, SessionWindows]) -> str:
    """HTML: one row per (state, window)."""
    e = html.escape
    head = ("<table><tr><th>state</th><th>window (cycles)</th><th>verdict</th><th>p</th><th>percentile</th>"
            "<th>delay (ms)</th><th>outside band</th><th>energy distance</th><th>ISO R vs realisations</th>"
            "<th>corridor</th><th>phase</th><th>magnitude</th><th>slope</th><th>ISO R percentile</th>"
            "<th>ISO R low-passed</th><th>departs at</th></tr>")
    rows = [f"<h3>{e(session)}</h3>", head]
    for s, sw in windows.items():
        for w in sw.windows:
            n = w.measured.shape[0]
            rows.append(
                f"<tr><td>{e(s)}</td><td>{w.start_cycle}-{w.start_cycle + n - 1}</td>"
                f"<td>{'consistent' if w.consistent else 'inconsistent'}</td><td>{w.p:.3f}</td>"
                f"<td>{w.percentile:.0f}</td><td>{w.delay_s * 1e3:.2f}</td>"
                f"<td>{100 * w.statistics['outside']:.0f} %</td><td>{w.statistics['energy']:.2f}</td>"
                f"<td>{w.iso['rating']:.3f}</td><td>{w.iso['corridor']:.3f}</td><td>{w.iso['phase']:.3f}</td>"
                f"<td>{w.iso['magnitude']:.3f}</td><td>{w.iso['slope']:.3f}</td><td>{w.iso_percentile:.0f}</td>"
                f"<td>{w.iso['lowpass_rating']:.3f}</td><td>{e(', '.join(w.departs) or '-')}</td></tr>")
    rows.append("</table>")
    return "".join(rows)


def window_section(items: Sequence, out: Path, slug: Callable[[str], str], save: Callable[[Figure, Path], Path],
                   img: Callable[[Path], str]) -> tuple[str, list[Path]]:
    """HTML and figure files of every session's windows (``items``: objects with ``identification``
    and ``windows``, {state: SessionWindows})."""
    parts = ["<h2>Five-cycle windows against every state's ensemble windows</h2>"]
    files: list[Path] = []
    for it in items:
        name = it.identification.session
        if not any(sw.windows for sw in it.windows.values()):
            parts.append(f"<p class='note'>{html.escape(name)}: no run of steady cycles long enough for a window</p>")
            continue
        own = it.windows.get(getattr(it, "state", None)) or next(iter(it.windows.values()))
        if own.delay is not None:
            parts.append(f"<p class='note'>{html.escape(name)}: sensor delay against {html.escape(own.state)}: "
                         f"{html.escape(own.delay.describe())}</p>")
        parts.append(window_table(name, it.windows))
        f = windows_side_by_side(name, it.windows, out / f"windows_{slug(name)}.png", save)
        files.append(f)
        parts.append(img(f))
        for s, sw in it.windows.items():
            if not sw.windows:
                continue
            g = window_figure(sw.windows[0], sw.band, name, out / f"window_{slug(name)}_{slug(s)}.png", save)
            files.append(g)
            parts.append(img(g))
    return "\n".join(parts), files
