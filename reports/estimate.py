"""The joint posterior of clearance and wear of one session, as a lab would put it in a report.

Clearance and wear are partly confounded (a larger clearance and a worn joint both soften and
spread the impacts), so the figure shows the joint posterior on the estimator's grid, not only the
two marginal intervals: its 50 % and 90 % highest-density regions, the marginal medians and 90 %
intervals, and the session's verdict. The posterior predictive figure puts the measured cycles'
features by crank angle in the band where a cycle of a bench at the posterior's parameter values
lies. Imports matplotlib (object API, no pyplot state).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from wearbench.validation.estimation.estimate import Estimate, EstimatorModel

__all__ = ["posterior_figure", "predictive_figure"]


def _hdr_levels(post: np.ndarray, masses: tuple[float, ...]) -> list[float]:
    """Density levels enclosing ``masses`` of the grid posterior (highest density first)."""
    flat = np.sort(post.ravel())[::-1]
    cum = np.cumsum(flat)
    return sorted(float(flat[min(np.searchsorted(cum, m), flat.size - 1)]) for m in masses)


def posterior_figure(estimate: Estimate, path: str | Path, model: EstimatorModel | None = None, *,
                     grid: tuple[np.ndarray, np.ndarray] | None = None) -> Path:
    """Write the joint posterior figure of ``estimate`` to ``path`` (PNG). The grid comes from
    ``model`` or ``grid`` = (clearances m, cycles); default: the estimate's own marginal ranges."""
    post = estimate.posterior
    if post is None:
        raise ValueError(f"estimate {estimate.session}: no posterior grid kept")
    if model is not None:
        gc, gn = model.grid_c, model.grid_n
    elif grid is not None:
        gc, gn = grid
    else:
        gc = np.linspace(estimate.meta["grid_c"][0], estimate.meta["grid_c"][1], post.shape[0])
        gn = np.linspace(estimate.meta["grid_n"][0], estimate.meta["grid_n"][1], post.shape[1])
    fig = Figure(figsize=(6.4, 4.8))
    ax = fig.add_subplot()
    mesh = ax.pcolormesh(gc * 1e3, gn / 1e3, post.T, shading="auto", cmap="Blues")
    fig.colorbar(mesh, ax=ax, label="posterior probability per grid cell")
    if post.max() > 0:
        levels = _hdr_levels(post, (0.5, 0.9))
        if levels[0] < levels[1]:
            ax.contour(gc * 1e3, gn / 1e3, post.T, levels=levels, colors=["0.2", "0.2"], linestyles=["--", "-"])
    c, n = estimate.clearance, estimate.cycles_run
    sided = [f"{name} {i.text(fmt)}" for name, i, fmt in (("clearance", c, lambda v: f"{v * 1e3:.3f} mm"),
                                                          ("cycles run", n, lambda v: f"{v / 1e3:.0f}k"))
             if i.kind != "central"]
    ax.errorbar([c.median * 1e3], [n.median / 1e3], xerr=[[(c.median - c.lo90) * 1e3], [(c.hi90 - c.median) * 1e3]],
                yerr=[[(n.median - n.lo90) / 1e3], [(n.hi90 - n.median) / 1e3]], fmt="o", color="C3",
                label="medians, 90 % intervals" + (f" (one-sided: {'; '.join(sided)})" if sided else ""))
    for i, scale, along_x in ((c, 1e3, True), (n, 1e-3, False)):  # a one-sided interval's closed end: the range's
        if i.kind != "central":
            end = (i.lo90 if i.kind == "upper bound" else i.hi90) * scale
            mark = {"marker": "|" if along_x else "_", "markersize": 14, "color": "C3", "ls": "none"}
            ax.plot([end] if along_x else [c.median * 1e3], [n.median / 1e3] if along_x else [end], **mark)
    ax.set_xlabel("radial clearance (mm)")
    ax.set_ylabel("cycles run (thousands)")
    ax.set_title(f"{estimate.session}: {estimate.cycles} cycles\n{estimate.verdict}", fontsize=8)
    ax.legend(loc="upper right", fontsize=7)
    path = Path(path)
    fig.savefig(path, dpi=110)
    return path


def predictive_figure(estimate: Estimate, path: str | Path) -> Path:
    """Write the posterior predictive band (5-95 % and median of one cycle's features, per block and
    crank-angle bin) with the session's measured cycles over it to ``path`` (PNG)."""
    band, x = estimate.band, estimate.measured
    if band is None or x is None:
        raise ValueError(f"estimate {estimate.session}: no predictive band kept")
    bins = int(estimate.meta["bins"])
    names = ["low-passed acceleration (m/s$^2$)"] + [f"log10 energy {lo:g}-{hi:g} Hz"
                                                      for lo, hi in estimate.meta["bands"]]
    angle = (np.arange(bins) + 0.5) * 360.0 / bins
    fig = Figure(figsize=(10, 2.2 + 1.6 * len(names)))
    axes = fig.subplots(len(names), 1, sharex=True, squeeze=False)[:, 0]
    for k, (ax, name) in enumerate(zip(axes, names, strict=True)):
        cols = slice(k * bins, (k + 1) * bins)
        ax.fill_between(angle, band[0, cols], band[2, cols], step="mid", color="tab:blue", alpha=0.25, lw=0,
                        label="posterior predictive 5-95 % of a cycle")
        ax.step(angle, band[1, cols], where="mid", color="tab:blue", lw=1.0, label="median")
        for i, row in enumerate(x[:, cols]):
            ax.step(angle, row, where="mid", color="black", lw=0.4, alpha=0.35,
                    label="measured cycles" if i == 0 else None)
        ax.set_ylabel(name, fontsize=8)
    axes[0].legend(loc="upper right", fontsize=7)
    axes[-1].set_xlim(0, 360)
    axes[-1].set_xlabel("crank angle (deg)")
    axes[0].set_title(f"{estimate.session}: {estimate.cycles} cycles, {100 * estimate.inside:.0f} % of the measured "
                      f"values inside the 90 % band\n{estimate.verdict}", fontsize=8)
    path = Path(path)
    fig.savefig(path, dpi=100)
    return path
