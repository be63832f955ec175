"""The identification part of the report: posterior table, band figures, model-reference scores.

``report.write_report`` calls :func:`identification_section` when sessions were identified against
theory ensembles. Matplotlib figures through ``report``'s helpers' conventions (object API, no
pyplot). Imports validation.identify and validation.bands for types.
"""

from __future__ import annotations

import html
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from wearbench.reports.windows import NOTES as WINDOW_NOTES
from wearbench.reports.windows import window_section
from wearbench.validation.comparison.bands import BandComparison
from wearbench.validation.comparison.windows import SessionWindows
from wearbench.validation.estimation.estimate import Estimate
from wearbench.validation.inference.identify import Identification

__all__ = ["IdentifiedSession", "identification_section"]

NOTES = (
    ("Theory is an ensemble: each candidate state is simulated many times, each realisation a bench "
    "drawn within the bench file's [tolerances] (masses, inertias, lengths, ground points, friction, "
    "restitution, contact exponent, motor speed and ripple) from a random start, settled. Impacts are "
    "chaotic, so a session is compared with the statistics of the ensemble's cycles, never with one "
    "simulated trajectory."),
    ("Posterior: Gaussian likelihood of the session's mean cycle features (low-passed 50 Hz curve and "
    "impact energy in the 50-150, 150-400 and 400-1000 Hz bands, in 20 deg crank-angle bins) under each "
    "state's hierarchical ensemble statistics (covariances pooled over the candidates), tempered by a factor calibrated on held-out realisations; uniform prior. A state is "
    "named only at p >= the threshold, else 'undecided'; 'none of the candidates' when no state passes "
    "the consistency test: the session's distance in all features, and along the directions to the other "
    "candidates, each against the same distance of held-out realisations (p >= 0.001 and 0.01)."),
    *WINDOW_NOTES,
    ("Estimate (when asked for): the clearance shared by the clearance joints and the wear as cycles run "
    "along the bench's own Archard trajectory, with the wear depth (the largest clearance growth of any "
    "joint) that goes with them; posterior medians and central 90 % credible intervals from an emulator of "
    "the ensemble statistics over a design of clearances and cycles run, with the likelihood of the "
    "identification; 'no parameter value explains it' when the session's smallest distance over the grid "
    "fails the consistency test (p < 0.001). The predictive band is where one cycle of a bench at the "
    "posterior's parameter values lies (5-95 %), measured cycles over it."),
)


@dataclass
class IdentifiedSession:
    """One session's identification, its bands against the top (or named) ``state``, and its windows
    against every state (``decided``: the identification named ``state``)."""

    identification: Identification
    bands: BandComparison
    windows: dict[str, SessionWindows]
    state: str
    decided: bool
    estimate: Estimate | None = None

    @property
    def window_verdict(self) -> str:
        """The one window verdict of the session: against the identified state, or why there is none."""
        sw = self.windows.get(self.state)
        if not self.decided:
            return f"cannot decide: identification {self.identification.verdict}"
        return "no window" if sw is None else sw.label


def _delay(item: IdentifiedSession) -> str:
    sw = item.windows.get(item.state)
    if sw is None or not sw.windows:
        return "-"
    return f"{np.median([w.delay_s for w in sw.windows]) * 1e3:.2f}"


def _band_figure(item: IdentifiedSession, path: Path, save: Callable[[Figure, Path], Path]) -> Path:
    b = item.bands
    fig = Figure(figsize=(10, 4.2))
    ax = fig.subplots()
    ax.fill_between(b.angle_deg, b.lo, b.hi, color="tab:red", alpha=0.2, lw=0, label=f"{b.state}: 5-95 %")
    ax.plot(b.angle_deg, b.median, color="tab:red", lw=1.0, label=f"{b.state}: median")
    for k, curve in enumerate(b.measured):
        ax.plot(b.angle_deg, curve, color="black", lw=0.4, alpha=0.35, label="measured cycles" if k == 0 else None)
    ax.plot(b.angle_deg, b.lo, color="tab:red", lw=0.5)
    ax.plot(b.angle_deg, b.hi, color="tab:red", lw=0.5)
    twin = ax.twinx()
    per_bin = b.outside.reshape(36, -1).mean(axis=1) if b.outside.size % 36 == 0 else b.outside
    edges = np.linspace(0, 360, per_bin.size + 1)
    twin.stairs(100 * per_bin, edges, color="tab:blue", lw=1.0)
    twin.set_ylabel("measured samples outside the band, per 10 deg (%)", color="tab:blue")
    twin.set_ylim(0, 100)
    ax.set_xlim(0, 360)
    ax.set_xlabel("crank angle (deg)")
    ax.set_ylabel("acceleration, filtered as the theory's kept curves (m/s$^2$)")
    ax.set_title(f"{item.identification.session}: measured cycles in the band of {b.state}", fontsize=10)
    ax.legend(loc="upper right", fontsize=8)
    return save(fig, path)


def _posterior_figure(items: Sequence[IdentifiedSession], path: Path, save) -> Path:
    states = list(items[0].identification.posterior)
    fig = Figure(figsize=(2.5 + 1.6 * len(states), 1.2 + 0.55 * len(items)))
    ax = fig.subplots()
    grid = np.array([[it.identification.posterior[s] for s in states] for it in items])
    ax.imshow(grid, cmap="viridis", vmin=0, vmax=1, aspect="auto")
    for i in range(grid.shape[0]):
        for j in range(grid.shape[1]):
            ax.text(j, i, f"{grid[i, j]:.2f}", ha="center", va="center", fontsize=8,
                    color="black" if grid[i, j] > 0.6 else "white")
    ax.set_xticks(range(len(states)), states, rotation=20, ha="right", fontsize=8)
    ax.set_yticks(range(len(items)), [it.identification.session for it in items], fontsize=8)
    ax.set_title("posterior probability of each candidate state", fontsize=9)
    return save(fig, path)


def _notes(item: IdentifiedSession) -> list[str]:
    """The session's notes: its identification's (a flat posterior, a speed outside the validated ones,
    clipping, a diagnosis), where it leaves the top state's band, and its estimate's."""
    r = item.identification
    top = max(r.posterior, key=r.posterior.get)
    leaves = [f"leaves the band of {top}: " + ", ".join(r.leaves[top])] if r.leaves[top] else []
    own = [] if item.estimate is None else [f"estimate: {n}" for n in item.estimate.notes]
    return [*r.notes, *leaves, *own]


def _interval(i, scale: float, fmt: str) -> str:
    """Median and 90 % interval ("lo-hi", or "at most" / "at least" where one-sided)."""
    return f"{i.median * scale:{fmt}} [{i.text(lambda v: f'{v * scale:{fmt}}')}]"


def _estimate_cells(est: Estimate | None) -> str:
    """The estimate's cells of the first table: clearance, cycles run, wear depth, whether a value explains it."""
    if est is None:
        return "<td>-</td>" * 4
    if not est.explains:
        return f"<td colspan='3'>{html.escape(est.verdict)}</td><td>no (p {est.p_value:.2g})</td>"
    if est.flat:  # the intervals are the prior's: said, not shown as a measurement
        return f"<td colspan='3'>{html.escape(est.verdict)}</td><td>yes (p {est.p_value:.2g})</td>"
    return (f"<td>{_interval(est.clearance, 1e3, '.3f')}</td><td>{_interval(est.cycles_run, 1e-3, ',.0f')}</td>"
            f"<td>{_interval(est.depth, 1e6, '.1f')}</td><td>yes (p {est.p_value:.2g})</td>")


def identification_section(items: Sequence[IdentifiedSession], out: Path, slug: Callable[[str], str],
                           save: Callable[[Figure, Path], Path], img: Callable[[Path], str],
                           threshold: float) -> tuple[str, list[Path], list[dict]]:
    """HTML of the section, its figure files, and its JSON rows (one per session)."""
    e = html.escape
    states = list(items[0].identification.posterior)
    estimated = any(it.estimate is not None for it in items)
    files = [_posterior_figure(items, out / "posteriors.png", save)]
    parts = [f"<h2>Which state explains each session (named at p &ge; {threshold:g})</h2><table><tr>"
             "<th>session</th><th>cycles</th>" + "".join(f"<th>p({e(s)})</th>" for s in states)
             + "<th>verdict</th>" + ("<th>clearance (mm), median [90 %]</th><th>cycles run (thousands)</th>"
                                     "<th>wear depth (µm)</th><th>a parameter value explains it</th>"
                                     if estimated else "") + "<th>windows against it</th><th>sensor delay (ms)</th><th>explained by</th>"
             "<th>cycles to decide</th><th>cycles inside band</th>"
             "<th>peak |a| (kept curves) measured / theory p50 (m/s²)</th><th>notes</th></tr>"]
    rows = []
    for it in items:
        r = it.identification
        needed = "-" if r.cycles_needed is None else str(r.cycles_needed)
        b = it.bands.summary()
        top = max(r.posterior, key=r.posterior.get)
        parts.append(f"<tr><td>{e(r.session)}</td><td>{r.cycles}</td>"
                     + "".join(f"<td>{r.posterior[s]:.3f}</td>" for s in states)
                     + f"<td>{e(r.verdict)}</td>" + (_estimate_cells(it.estimate) if estimated else "")
                     + f"<td>{e(it.window_verdict)}</td><td>{_delay(it)}</td>"
                     f"<td>{e(', '.join(s for s in states if r.explains[s]) or 'none')}</td>"
                     f"<td>{needed}</td><td>{100 * r.inside[top]:.0f} % ({e(top)})</td>"
                     f"<td>{b['peak_acc_measured_median']:.0f} / {b['peak_acc_theory_p5_p50_p95'][1]:.0f}</td>"
                     f"<td>{e('; '.join(_notes(it)))}</td></tr>")
        rows.append({**r.to_dict(), "bands": b, "window_state": it.state, "window_verdict": it.window_verdict,
                     "windows": {st: sw.summary() for st, sw in it.windows.items()},
                     **({"estimate": it.estimate.to_dict()} if it.estimate is not None else {})})
    parts.append("</table>")
    parts.append(img(files[0]))
    if estimated:
        from wearbench.reports.estimate import posterior_figure, predictive_figure

        parts.append("<h2>Clearance and wear of each session</h2>")
        for it in items:
            if it.estimate is None:
                continue
            name = slug(it.identification.session)
            for f in (posterior_figure(it.estimate, out / f"estimate_{name}.png"),
                      predictive_figure(it.estimate, out / f"predictive_{name}.png")):
                files.append(f)
                parts.append(img(f))
    html_windows, window_files = window_section(items, out, slug, save, img)
    parts.append(html_windows)
    files += window_files
    for it in items:
        f = _band_figure(it, out / f"band_{slug(it.identification.session)}.png", save)
        files.append(f)
        parts.append(img(f))
    return "\n".join(parts), files, rows
