"""The comparison report on disk: PNG figures, ``scores.json`` and a self-contained ``report.html``.

Holds ``write_report``, ``ComparisonReport`` and ``compare_sessions`` (compare, then write). Figures follow the paper: test and theory overlaid
over five cycles with the residual (its figs. 37, 39), measured windows of several sessions side by
side (figs. 36, 38), plus amplitude spectra and the score table. Matplotlib (object API, no pyplot); imports
validation.compare (the comparisons) and the metrics for grading; compare never imports it.
"""

from __future__ import annotations

import base64
import html
import json
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle
from wearbench.reports.identification import NOTES as IDENTIFY_NOTES
from wearbench.reports.identification import IdentifiedSession, identification_section
from wearbench.validation.comparison.compare import (
    CompareOptions,
    SessionComparison,
    TheoryRanking,
    compare_session,
)
from wearbench.validation.comparison.metrics import grade
from wearbench.validation.measurement.cycles import crank_turns
from wearbench.validation.measurement.session import MeasuredSession

__all__ = ["ComparisonReport", "compare_sessions", "slug", "write_report"]

TEST_STYLE = {"color": "black", "lw": 0.8, "label": "test"}
THEORY_STYLE = {"color": "tab:red", "lw": 0.8, "label": "theory", "alpha": 0.85}
TABLE_METRICS = (("iso_rating", "ISO 18571 R"), ("iso_corridor", "corridor"), ("iso_phase", "phase"),
                 ("iso_magnitude", "magnitude"), ("iso_slope", "slope"), ("nrmse", "NRMSE"),
                 ("correlation", "correlation"), ("peak_error", "peak error"), ("peak_time_shift", "peak dt (s)"),
                 ("sg_magnitude", "S&G M"), ("sg_phase", "S&G P"), ("sg_comprehensive", "S&G C"))

DEPARTURES = (
    ("ISO/TS 18571 with the standard's parameters and weights, except: the phase search is limited to "
    "+/- max_shift_cycles of one crank cycle and to the sensor's plausible delay max_delay (a five-cycle "
    "periodic window shifted by the standard's 20 % "
    "= one cycle matches itself), still normalised by 20 % of the window; the DTW of the magnitude score "
    "runs inside a Sakoe-Chiba band of dtw_band_cycles of a cycle (the reference implementation uses 10 % "
    "of the window: half a cycle here, which pairs an impact with its neighbour, at 10x the cost); "
    "signals are scored at the session's sample rate (the standard asks for 10 kHz)."),
    ("Before scoring, the theory is looked up at the measured crank angle of each sample, both signals get "
    "the same bias removal and zero-phase filter, and a residual time shift found by cross-correlation "
    "(sub-sample) is removed from the theory; it is reported as 'shift'. The ISO phase score then rates "
    "what is left after that shift."),
    ("NRMSE is normalised by the test's peak-to-peak range; peak error is relative to the test's peak "
    "|a|; Sprague-Geers values and NRMSE are errors (0 is perfect), the ISO scores and correlation are 1 "
    "when perfect."),
)


@dataclass
class ComparisonReport:
    """What ``write_report`` produced: the comparisons and the files on disk."""

    sessions: list[SessionComparison]
    out_dir: Path
    html: Path
    scores_json: Path
    figures: list[Path] = field(default_factory=list)

    @property
    def scores(self) -> dict:
        return json.loads(self.scores_json.read_text())

    def moved_to(self, out_dir: str | Path) -> ComparisonReport:
        """This report with its paths in ``out_dir``, where its files were moved (written to a
        temporary folder under the output-file policy, ``bench.output_file.output_folder``)."""
        out = Path(out_dir)

        def move(p: Path) -> Path:
            return out / p.relative_to(self.out_dir)

        return ComparisonReport(self.sessions, out, move(self.html), move(self.scores_json),
                                [move(f) for f in self.figures])


def slug(text: str) -> str:
    """A session or state label as a file name (``dA/s`` -> ``dA_s``)."""
    return re.sub(r"[^A-Za-z0-9._-]+", "_", text).strip("_") or "session"


def _finite(x):
    """JSON-safe: NaN/inf become None (strict JSON has no NaN)."""
    if isinstance(x, dict):
        return {str(k): _finite(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_finite(v) for v in x]
    if isinstance(x, (np.floating, float)):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def _figure(rows: int = 1, cols: int = 1, **kw):
    """A figure without pyplot (no global backend or figure registry touched) and its axes."""
    fig = Figure(figsize=kw.pop("figsize"))
    return fig, fig.subplots(rows, cols, **kw)


def _save(fig: Figure, path: Path) -> Path:
    fig.savefig(path, dpi=110, bbox_inches="tight")
    return path


def _sensor(c: SessionComparison) -> str:
    """The accelerometer's name in the session's bench (what its samples are), else "measured"."""
    bench = c.session.bench
    return next((s.name for s in bench.sensors if s.kind == "accelerometer"), "measured") if bench else "measured"


def _overlay(c: SessionComparison, path: Path) -> Path:
    w = c.windows[0]
    fig, (ax, axr) = _figure(2, 1, figsize=(10, 5.2), sharex=True, gridspec_kw={"height_ratios": [3, 1.3]})
    ax.plot(w.time, w.test, **TEST_STYLE)
    ax.plot(w.time, w.theory, **THEORY_STYLE)
    ax.set_ylabel(f"{_sensor(c)} acceleration (m/s$^2$)")
    ax.set_title(f"{c.label}: cycles {w.start_cycle}-{w.start_cycle + c.options.windows.cycles - 1}, "
                 f"R = {w.scores.iso_rating:.3f} ({w.scores.iso_grade}), shift {w.shift_s * 1e3:+.2f} ms")
    ax.legend(loc="upper right")
    axr.plot(w.time, w.test - w.theory, color="tab:blue", lw=0.7)
    axr.axhline(0, color="grey", lw=0.5)
    axr.set_ylabel("residual")
    axr.set_xlabel("time from window start (s)")
    return _save(fig, path)


def _spectrum(c: SessionComparison, path: Path) -> Path:
    """Welch amplitude spectral density of the (filtered, aligned) window, test and theory."""
    from scipy.signal import welch

    w = c.windows[0]
    fs = c.session.fs
    nper = min(w.test.size, 4096)
    fig, ax = _figure(figsize=(10, 3.6))
    top = 0.0
    for sig, style in ((w.test, TEST_STYLE), (w.theory, THEORY_STYLE)):
        f, p = welch(sig, fs=fs, nperseg=nper)
        asd = np.sqrt(p)
        top = max(top, float(asd[1:].max()))
        ax.semilogy(f[1:], asd[1:], **style)
    corner = c.options.filter.corner
    ax.set_xlim(0, min(fs / 2, 3 * corner if corner else fs / 2))
    ax.set_ylim(top * 1e-5, top * 2)
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("amplitude density (m/s$^2$/$\\sqrt{Hz}$)")
    ax.set_title(f"{c.label}: spectra of the window (Welch, {c.options.filter.label})")
    ax.legend(loc="upper right")
    return _save(fig, path)


def _by_angle(c: SessionComparison, path: Path) -> Path:
    """The window's cycles folded onto crank angle (from the index angle): the crank-angle view."""
    w = c.windows[0]
    s = c.session
    enc = s.encoder
    angle = np.interp(w.time + w.t_start, enc["time"].to_numpy(float), enc["angle"].to_numpy(float))
    crank = crank_turns(angle, start_angle=s.start_angle)
    cycle = crank.cycle
    deg = np.degrees(crank.progress - crank.direction * s.start_angle) % 360.0
    fig, ax = _figure(figsize=(10, 3.8))
    for k in np.unique(cycle):
        m = cycle == k
        order = np.argsort(deg[m])
        first = k == cycle[0]
        ax.plot(deg[m][order], w.test[m][order], color="black", lw=0.5, alpha=0.6,
                label="test" if first else None)
        ax.plot(deg[m][order], w.theory[m][order], color="tab:red", lw=0.5, alpha=0.6,
                label="theory" if first else None)
    ax.set_xlim(0, 360)
    ax.set_xlabel("crank angle from the index pulse (deg)")
    ax.set_ylabel(f"{_sensor(c)} acceleration (m/s$^2$)")
    ax.set_title(f"{c.label}: the window's cycles by crank angle")
    ax.legend(loc="upper right")
    return _save(fig, path)


def _side_by_side(comparisons: Sequence[SessionComparison], path: Path, *, with_theory: bool) -> Path:
    n = len(comparisons)
    fig, axes = _figure(n, 1, figsize=(10, 2.3 * n + 0.6), sharex=True, sharey=True, squeeze=False)
    for ax, c in zip(axes[:, 0], comparisons):
        w = c.windows[0]
        ax.plot(w.time, w.test, **TEST_STYLE)
        if with_theory:
            ax.plot(w.time, w.theory, **THEORY_STYLE)
        ax.set_title(c.label, fontsize=9, loc="left")
        ax.set_ylabel("m/s$^2$")
    axes[0, 0].legend(loc="upper right", fontsize=8)
    axes[-1, 0].set_xlabel("time from window start (s)")
    fig.suptitle("test and theory, five cycles per session" if with_theory else
                 "measured acceleration, five cycles per session")
    return _save(fig, path)


def _score_table(comparisons: Sequence[SessionComparison]) -> str:
    """Every score of every session (mean ± sd over its windows) as an HTML table."""
    e = html.escape
    unique = len({c.label for c in comparisons}) == len(comparisons)
    out = ["<table class='scores'><tr><th>session</th>" + "".join(f"<th>{e(n)}</th>" for _, n in TABLE_METRICS)
           + "</tr>"]
    for c in comparisons:
        s = c.summary
        label = c.label if unique else f"{c.label} / {c.theory.label}"
        out.append(f"<tr><td>{e(label)}</td>" + "".join(
            f"<td>{s.loc[k, 'mean']:.3f} ± {s.loc[k, 'std']:.3f}</td>" for k, _ in TABLE_METRICS) + "</tr>")
    out.append("</table>")
    return "".join(out)


def _ranking(rankings: Mapping[str, Sequence[TheoryRanking]], path: Path) -> Path:
    """ISO rating of every session (rows) against every candidate theory (columns); best boxed."""
    sessions = list(rankings)
    named = {r.label for ranks in rankings.values() for r in ranks}  # a session's own theory in its column
    candidates = [s for s in sessions if s in named]
    candidates += sorted(named - set(candidates))
    grid = np.full((len(sessions), len(candidates)), np.nan)
    for i, name in enumerate(sessions):
        for r in rankings[name]:
            grid[i, candidates.index(r.label)] = r.rating
    fig, ax = _figure(figsize=(2.2 + 1.6 * len(candidates), 1.2 + 0.55 * len(sessions)))
    ax.imshow(grid, cmap="viridis", vmin=0, vmax=1, aspect="auto")
    for i, name in enumerate(sessions):
        best = candidates.index(rankings[name][0].label)
        for j in range(len(candidates)):
            if np.isfinite(grid[i, j]):
                ax.text(j, i, f"{grid[i, j]:.3f}", ha="center", va="center", fontsize=8,
                        color="black" if grid[i, j] > 0.6 else "white", weight="bold" if j == best else None)
        ax.add_patch(Rectangle((best - 0.5, i - 0.5), 1, 1, fill=False, edgecolor="tab:red", lw=2))
    ax.set_xticks(range(len(candidates)), candidates, rotation=20, ha="right", fontsize=8)
    ax.set_yticks(range(len(sessions)), sessions, fontsize=8)
    ax.set_xlabel("theory")
    ax.set_ylabel("measured session")
    ax.set_title("ISO/TS 18571 rating of each session against each theory (best boxed)", fontsize=9)
    return _save(fig, path)


def _summary(comparisons: Sequence[SessionComparison],
             rankings: Mapping[str, Sequence[TheoryRanking]]) -> list[dict]:
    """Per session: its score and grade, peak |a| measured and predicted, the best-explaining theory."""
    out = []
    for c in comparisons:
        rating = float(c.summary.loc["iso_rating", "mean"])
        d = c.to_dict()
        ranks = rankings.get(c.label)
        out.append({"session": c.label, "theory": c.theory.label, "windows": len(c.windows),
                    "iso_rating": rating, "grade": grade(rating), "peak_acc_measured": d["peak_acc_measured"],
                    "peak_acc_theory": d["peak_acc_theory"],
                    "best_explained_by": ranks[0].label if ranks else None,
                    "best_rating": ranks[0].rating if ranks else None})
    return out


def _img(path: Path) -> str:
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    return f'<img alt="{html.escape(path.stem)}" src="data:image/png;base64,{data}">'


def _html(comparisons: Sequence[SessionComparison], figures: dict, title: str, scores: dict,
          rankings: Mapping[str, Sequence[TheoryRanking]], identification: str = "") -> str:
    e = html.escape
    out = [(f"<!doctype html><html><head><meta charset='utf-8'><title>{e(title)}</title><style>"
           "body{font-family:sans-serif;max-width:1100px;margin:2em auto;color:#222}"
           "table{border-collapse:collapse;font-size:13px;margin:1em 0}td,th{border:1px solid #bbb;"
           "padding:3px 7px;text-align:right}th{background:#eee}td:first-child{text-align:left}"
           "img{max-width:100%}.note{font-size:12px;color:#555}</style></head><body>"),
           f"<h1>{e(title)}</h1>",
           (f"<p class='note'>generated {e(scores['generated'])}; filter: {e(scores['options']['filter'])}; "
           f"windows: {e(scores['options']['windows'])}</p>"),
           identification]
    if comparisons:
        out.append("<h2>Summary</h2><table><tr><th>session</th><th>theory</th><th>windows</th>"
                   "<th>ISO R (mean ± sd)</th><th>grade</th><th>peak |a| test (m/s²)</th><th>peak |a| theory (m/s²)</th>"
                   + ("<th>best explained by</th>" if rankings else "")
                   + "<th>shift (ms / deg)</th><th>NRMSE</th><th>correlation</th><th>S&amp;G C</th></tr>")
    for c, row in zip(comparisons, scores["summary"]):
        s = c.summary
        shift = np.mean([w.shift_s for w in c.windows]) * 1e3
        deg = np.mean([w.shift_deg for w in c.windows])
        best = f"<td>{e(row['best_explained_by'] or '-')}</td>" if rankings else ""
        out.append(f"<tr><td>{e(c.label)}</td><td>{e(c.theory.label)}</td><td>{len(c.windows)}</td>"
                   f"<td>{row['iso_rating']:.3f} ± {s.loc['iso_rating', 'std']:.3f}</td>"
                   f"<td>{row['grade']}</td><td>{row['peak_acc_measured']:.1f}</td>"
                   f"<td>{row['peak_acc_theory']:.1f}</td>{best}<td>{shift:+.2f} / {deg:+.2f}</td>"
                   f"<td>{s.loc['nrmse', 'mean']:.3f}</td><td>{s.loc['correlation', 'mean']:.3f}</td>"
                   f"<td>{s.loc['sg_comprehensive', 'mean']:.3f}</td></tr>")
    if comparisons:
        out.append("</table>")
    if rankings:
        out.append("<h2>Which theory explains each session best</h2><table><tr><th>session</th>"
                   "<th>best theory</th><th>ISO R</th><th>other candidates (ISO R)</th></tr>")
        for session, ranks in rankings.items():
            others = ", ".join(f"{e(r.label)} ({r.rating:.3f})" for r in ranks[1:])
            out.append(f"<tr><td>{e(session)}</td><td>{e(ranks[0].label)}</td><td>{ranks[0].rating:.3f} ± "
                       f"{ranks[0].rating_std:.3f}</td><td>{others}</td></tr>")
        out.append("</table>")
    for key, heading in (("ranking", "Every session against every theory"), ("sessions", "Sessions side by side")):
        if figures.get(key):
            out.append(f"<h2>{heading}</h2>" + "".join(_img(p) for p in figures[key]))
    if comparisons:
        out.append("<h2>Scores (mean ± sd over windows)</h2>" + _score_table(comparisons))
    for i, c in enumerate(comparisons):
        out.append(f"<h2>{e(c.label)} against {e(c.theory.label)}</h2>")
        out.append("".join(_img(p) for p in figures.get(i, [])))
        out.append("<table><tr><th>window (cycles)</th><th>t (s)</th><th>shift (ms)</th>"
                   + "".join(f"<th>{e(n)}</th>" for _, n in TABLE_METRICS) + "</tr>")
        for w in c.windows:
            sd = w.scores.to_dict()
            out.append(f"<tr><td>{w.start_cycle}-{w.start_cycle + c.options.windows.cycles - 1}</td>"
                       f"<td>{w.t_start:.3f}-{w.t_end:.3f}</td><td>{w.shift_s * 1e3:+.2f}</td>"
                       + "".join(f"<td>{sd[k]:.3f}</td>" for k, _ in TABLE_METRICS) + "</tr>")
        out.append("</table>")
        if c.skipped:
            out.append("<p class='note'>skipped: " + "; ".join(f"cycle {s}: {e(r)}" for s, r in c.skipped)
                       + "</p>")
    notes = (DEPARTURES if comparisons else ()) + (IDENTIFY_NOTES if identification else ())
    out.append("<h2>Method notes</h2><ul class='note'>" + "".join(f"<li>{e(d)}</li>" for d in notes)
               + "</ul></body></html>")
    return "\n".join(out)


def write_report(comparisons: Sequence[SessionComparison], out_dir: str | Path, *,
                 title: str = "wearbench: measurement against theory",
                 rankings: Mapping[str, Sequence[TheoryRanking]] | None = None,
                 identified: Sequence[IdentifiedSession] = (), threshold: float = 0.9,
                 options: Mapping[str, Any] | None = None) -> ComparisonReport:
    """Write figures, ``scores.json`` and ``report.html`` for ``comparisons`` into ``out_dir``.

    rankings: optional ``rank_theories`` results by session label (best first), reported as the
    theory (e.g. wear stage) that best explains each session. identified: sessions identified against
    theory ensembles (posteriors, bands, model-reference scores), reported first; ``threshold`` is
    the probability at which a state was named. options: what the page's note states (``filter``,
    ``windows``; default the first comparison's options).
    """
    if not comparisons and not identified:
        raise ValueError("report: no comparisons to write")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    figures: dict[int | str, list[Path]] = {}  # per comparison (index), "sessions", "ranking"
    used: set[str] = set()
    for i, c in enumerate(comparisons):
        name = slug(c.label)
        while name in used:
            name += "_"
        used.add(name)
        figures[i] = [_overlay(c, out / f"overlay_{name}.png"), _by_angle(c, out / f"angle_{name}.png"),
                      _spectrum(c, out / f"spectrum_{name}.png")]
    if len(comparisons) > 1:
        figures["sessions"] = [_side_by_side(comparisons, out / "sessions_measured.png", with_theory=False),
                               _side_by_side(comparisons, out / "sessions_comparison.png", with_theory=True)]
    if rankings:
        figures["ranking"] = [_ranking(rankings, out / "ranking.png")]
    section, rows = "", []
    if identified:
        section, files, rows = identification_section(identified, out, slug, _save, _img, threshold)
        figures["identification"] = files
    options = dict(options) if options is not None else comparisons[0].options.to_dict()
    scores = {"generated": datetime.now(UTC).isoformat(timespec="seconds"), "title": title,
              "options": options,
              "method_notes": list((DEPARTURES if comparisons else ()) + (IDENTIFY_NOTES if identified else ())),
              "summary": _summary(comparisons, rankings or {}),
              "identification": rows,
              "sessions": [c.to_dict() for c in comparisons],
              "rankings": {k: [{"label": r.label, "rating": r.rating, "rating_std": r.rating_std} for r in v]
                           for k, v in (rankings or {}).items()}}
    scores_path = out / "scores.json"
    scores_path.write_text(json.dumps(_finite(scores), indent=2, allow_nan=False))
    html_path = out / "report.html"
    html_path.write_text(_html(comparisons, figures, title, scores, rankings or {}, section), encoding="utf-8")
    files = [p for ps in figures.values() for p in ps]
    return ComparisonReport(list(comparisons), out, html_path, scores_path, files)


def compare_sessions(paths: Sequence[str | Path | MeasuredSession], out_dir: str | Path, *,
                     theories: Sequence[Any] | Any = None, options: CompareOptions | None = None,
                     labels: Sequence[str] | None = None, title: str = "wearbench: measurement against theory"):
    """Compare each session with its theory and write ``report.html``, ``scores.json`` and figures
    to ``out_dir``. ``theories``: one for all sessions, one per session, or None (simulate each).
    Returns the :class:`ComparisonReport`."""
    options = options or CompareOptions()
    if not isinstance(theories, (list, tuple)):
        theories = [theories] * len(paths)
    if len(theories) != len(paths):
        raise ValueError(f"compare: {len(theories)} theories for {len(paths)} sessions; give one, or one per session")
    comparisons = []
    for i, (p, th) in enumerate(zip(paths, theories)):
        lab = labels[i] if labels else None
        comparisons.append(compare_session(p, th, options=options, label=lab))
    return write_report(comparisons, out_dir, title=title)
