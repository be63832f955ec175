"""The wear-over-life figure of ``wearbench track``: each session's wear depth against cycles run,
the Archard prediction with the fitted coefficient, the clearance limit seen from the last session
(the remaining cycles' interval, its verdict) and the cycles beyond the design's range of wear."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from wearbench.validation.estimation.track import Track

__all__ = ["design_end", "track_figure"]


def design_end(track: Track) -> float | None:
    """Cycles from new past which the bench, at the median wear factor, leaves the estimator's range
    of wear (the depth beyond it is extrapolated); None when the track does not say."""
    if track.design_cycles is None or not track.factor.median > 0:
        return None
    return track.design_cycles / track.factor.median


def track_figure(track: Track, path, *, title: str = "wear over the bench's life"):
    """Wear depth against cycles run: each session's interval, the Archard prediction with the
    fitted coefficient (median, 90 % band), the clearance limit with the cycles that remain after the
    last session (90 %, from the last session on) and its verdict, and the cycles past the design's
    range of wear at the median factor hatched. Returns the path (PNG)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.4, 4.4))
    ax = fig.add_subplot()
    n = np.array([p[0] for p in track.prediction]) / 1e3
    ax.fill_between(n, [p[1].lo90 * 1e6 for p in track.prediction], [p[1].hi90 * 1e6 for p in track.prediction],
                    color="C0", alpha=0.25, label="Archard, fitted coefficient: 90 %")
    ax.plot(n, [p[1].median * 1e6 for p in track.prediction], color="C0", label="median")
    x = np.array(track.cycles_run) / 1e3
    med = np.array([d.median for d in track.depth]) * 1e6
    ax.errorbar(x, med, yerr=[med - np.array([d.lo90 for d in track.depth]) * 1e6,
                              np.array([d.hi90 for d in track.depth]) * 1e6 - med], fmt="o", color="C3",
                label="sessions: wear depth, 90 %")
    if track.limit is not None:
        ax.axhline((track.limit - track.clearance.median) * 1e6, color="k", ls="--",
                   label=f"limit {track.limit * 1e3:g} mm (from the median clearance)")
        ahead = track.ahead
        if ahead is not None and ahead.remaining is not None and ahead.p_reached < 0.95:
            r = ahead.remaining
            ax.axvspan((ahead.last + r.lo90) / 1e3, (ahead.last + r.hi90) / 1e3, color="0.5", alpha=0.2,
                       label=f"limit reached after the last session (P not yet {1 - ahead.p_reached:.2f}): 90 %"
                       + ("" if r.kind == "central" else f", {r.kind}: {r.text(lambda v: f'{v / 1e3:,.0f}k')} more"))
    end = design_end(track)
    right = max(n[-1], *(ax.get_xlim()[1:]))
    if end is not None and end / 1e3 < right:
        ax.axvspan(end / 1e3, right, facecolor="none", edgecolor="0.6", hatch="//", lw=0,
                   label="beyond the design's range of wear at the median factor (extrapolated)")
        ax.set_xlim(right=right)
    k = track.factor
    ax.set_title(f"{title}\nwear coefficient {track.coefficient.median:.3g} 1/Pa "
                 f"({k.median:.2f}x the file's, 90 % {k.lo90:.2f}-{k.hi90:.2f})", fontsize=8)
    fig.subplots_adjust(bottom=0.2 if track.ahead is not None else 0.16)
    if track.ahead is not None:
        fig.text(0.01, 0.045, f"limit {track.limit * 1e3:g} mm: {track.ahead.verdict}", fontsize=6, wrap=True)
    fig.text(0.01, 0.01, f"move from new to worn {track.move['described']}" if track.move else
             "no measured move from new to worn: with fewer than three worn sessions the coefficient is biased low",
             fontsize=5, color="0.3", wrap=True)
    ax.set_xlabel("cycles run (thousands)")
    ax.set_ylabel("wear depth: clearance growth (um)")
    ax.legend(fontsize=7, loc="upper left")
    fig.savefig(Path(path), dpi=110)
    return Path(path)
