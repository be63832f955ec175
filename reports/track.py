"""The wear-over-life figure of ``wearbench track``: each session's wear depth against cycles run,
the Archard prediction with the fitted coefficient and the clearance limit."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from wearbench.validation.inference.track import Track

__all__ = ["track_figure"]

def track_figure(track: Track, path, *, title: str = "wear over the bench's life"):
    """Wear depth against cycles run: each session's interval, the Archard prediction with the
    fitted coefficient (median, 90 % band) and the clearance limit. Returns the path (PNG)."""
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
        if track.cycles_to_limit is not None:
            ax.axvspan(track.cycles_to_limit.lo90 / 1e3, track.cycles_to_limit.hi90 / 1e3, color="0.5", alpha=0.2,
                       label="cycles to the limit: 90 %")
    k = track.factor
    ax.set_title(f"{title}\nwear coefficient {track.coefficient.median:.3g} 1/Pa "
                 f"({k.median:.2f}x the file's, 90 % {k.lo90:.2f}-{k.hi90:.2f})", fontsize=8)
    fig.subplots_adjust(bottom=0.16)
    fig.text(0.01, 0.01, f"move from new to worn {track.move['described']}" if track.move else
             "no measured move from new to worn: with fewer than three worn sessions the coefficient is biased low",
             fontsize=5, color="0.3", wrap=True)
    ax.set_xlabel("cycles run (thousands)")
    ax.set_ylabel("wear depth: clearance growth (um)")
    ax.legend(fontsize=7, loc="upper left")
    fig.savefig(Path(path), dpi=110)
    return Path(path)
