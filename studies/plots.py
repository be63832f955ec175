"""Figures in the style of the paper's figs 9-17: slider kinematics, contact forces, journal centre
trajectories inside the clearance circle, Poincare sections and phase portraits.

Holds one function per figure (each takes a :class:`SimulationResult`, or several for comparisons,
and returns a matplotlib Figure) and :func:`save_figures` (PNG and SVG). Imports matplotlib (Agg),
numpy and the results type; nothing here computes physics.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from wearbench.model.simulation import SimulationResult

__all__ = [
    "contact_force_figure",
    "phase_figure",
    "poincare_figure",
    "save_figures",
    "slider_figure",
    "trajectory_figure",
]


def _label(r: SimulationResult, i: int) -> str:
    return r.summary.get("label") or f"run {i + 1}"


def _crank_deg(r: SimulationResult) -> tuple[np.ndarray, str]:
    cols = [c for c in r.table.columns if c.startswith("theta_")]
    if not cols:
        return r.table["t"].to_numpy(), "time (s)"
    th = r.table[cols[0]].to_numpy()
    return np.degrees(np.abs(th - th[0])), f"crank angle {cols[0][6:]} (deg)"


def slider_figure(results: Sequence[SimulationResult]) -> plt.Figure:
    """Slider displacement, velocity and acceleration against crank angle (paper figs 9-11)."""
    fig, axes = plt.subplots(3, 1, figsize=(7, 8), sharex=True)
    for i, r in enumerate(results):
        x, xlabel = _crank_deg(r)
        for ax, col, unit in zip(axes, ("slider_pos", "slider_vel", "slider_acc"), ("m", "m/s", "m/s$^2$")):
            ax.plot(x, r.table[col], lw=0.8, label=_label(r, i))
            ax.set_ylabel(f"{col.split('_')[1]} ({unit})")
    axes[0].set_title("slider displacement, velocity and acceleration")
    axes[-1].set_xlabel(xlabel)
    axes[0].legend(loc="best", fontsize=8)
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def contact_force_figure(results: Sequence[SimulationResult]) -> plt.Figure:
    """Normal contact force of each clearance joint against crank angle (paper figs 12-13)."""
    joints = list(results[0].summary["peak_fn"])
    fig, axes = plt.subplots(max(1, len(joints)), 1, figsize=(7, 3 * max(1, len(joints))), squeeze=False)
    for ax, j in zip(axes[:, 0], joints):
        for i, r in enumerate(results):
            x, xlabel = _crank_deg(r)
            ax.plot(x, r.table[f"{j}_fn"], lw=0.8, label=_label(r, i))
        ax.set_ylabel(f"contact force {j} (N)")
        ax.set_xlabel(xlabel)
        ax.grid(alpha=0.3)
        ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    return fig


def _joint_panels(results: Sequence[SimulationResult], height: float) -> tuple[list[str], plt.Figure, np.ndarray]:
    """The clearance joints of ``results`` and a row of one panel per joint (one panel if none)."""
    joints = list(results[0].summary["peak_fn"])
    n = max(1, len(joints))
    fig, axes = plt.subplots(1, n, figsize=(4.5 * n, height), squeeze=False)
    return joints, fig, axes[0]


def trajectory_figure(results: Sequence[SimulationResult]) -> plt.Figure:
    """Journal centre trajectory relative to the bearing centre inside the clearance circle (figs 14-15)."""
    joints, fig, axes = _joint_panels(results, height=4.5)
    for ax, j in zip(axes, joints):
        for i, r in enumerate(results):
            ax.plot(r.table[f"{j}_ex"] * 1e3, r.table[f"{j}_ey"] * 1e3, lw=0.6, label=_label(r, i))
        if results[0].scene is not None:
            p = results[0].scene.clearance_params(j)
            c = (p["bearing_radius"] - p["journal_radius"]) * 1e3
            a = np.linspace(0, 2 * math.pi, 361)
            ax.plot(c * np.cos(a), c * np.sin(a), "k--", lw=0.8, label="clearance circle")
        ax.set_aspect("equal")
        ax.set_xlabel("e$_x$ (mm)")
        ax.set_ylabel("e$_y$ (mm)")
        ax.set_title(f"journal centre trajectory, joint {j}")
        ax.legend(loc="upper right", fontsize=7)
    fig.tight_layout()
    return fig


def poincare_figure(results: Sequence[SimulationResult]) -> plt.Figure:
    """Poincare section of each clearance joint: (e_x, e_y) velocity map sampled once per crank revolution
    (fig. 16); falls back to the slider when the scene has no clearance joint."""
    joints, fig, axes = _joint_panels(results, height=4)
    for ax, j in zip(axes, joints or [None]):
        for i, r in enumerate(results):
            cols = (f"{j}_ex", f"{j}_ey") if j else ("slider_pos", "slider_vel")
            sec = r.poincare(cols)
            ax.plot(sec[cols[0]], sec[cols[1]], "o", ms=3, label=_label(r, i))
        ax.set_xlabel(cols[0])
        ax.set_ylabel(cols[1])
        ax.set_title(f"Poincare section {j or 'slider'} (one point per revolution)")
        ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def phase_figure(results: Sequence[SimulationResult]) -> plt.Figure:
    """Phase portraits of the eccentricity (e_x vs de_x/dt) of each clearance joint (fig. 17)."""
    joints, fig, axes = _joint_panels(results, height=4)
    for ax, j in zip(axes, joints):
        for i, r in enumerate(results):
            ph = r.phase(j)
            ax.plot(ph["ex"] * 1e3, ph["vx"], lw=0.5, label=_label(r, i))
        ax.set_xlabel("e$_x$ (mm)")
        ax.set_ylabel("de$_x$/dt (m/s)")
        ax.set_title(f"phase portrait, joint {j}")
        ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def save_figures(results: SimulationResult | Sequence[SimulationResult], folder: str | Path,
                 formats: Sequence[str] = ("png", "svg")) -> list[Path]:
    """Write every figure that applies to ``folder`` in each format; returns the paths written."""
    if isinstance(results, SimulationResult):
        results = [results]
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    makers = {"slider": slider_figure}
    if results[0].summary["peak_fn"]:
        makers.update(contact_force=contact_force_figure, trajectory=trajectory_figure,
                      phase=phase_figure)
        if results[0].scene is not None and results[0].scene.drivers:
            makers["poincare"] = poincare_figure
    paths = []
    for name, make in makers.items():
        fig = make(results)
        for fmt in formats:
            path = folder / f"{name}.{fmt}"
            fig.savefig(path, dpi=120)
            paths.append(path)
        plt.close(fig)
    return paths
