"""Figures of a study case, one line per worn state, drawn with :mod:`wearbench.studies.plots`: the
paper's figures 9-17 (wear study) and 22-32 (clearance study) analogues: slider outputs, contact
forces, journal centre trajectories, Poincare sections (one point per crank revolution) and phase
portraits.

Imports matplotlib (through the model's plots), the model contract and nothing of the CLI.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt

__all__ = ["FIGURES", "plot_case_dynamics"]

# paper figure numbers per figure: (wear study, clearance study)
FIGURES = {"slider": ("09-11", "22-24"), "contact_force": ("12", "25-26"), "trajectory": ("13", "27-28"),
           "poincare": ("14-15", "29-30"), "phase": ("16-17", "31-32")}


def plot_case_dynamics(result, bench, out: str | Path, *, clearance_study: bool = False,
                       suffix: str = "") -> list[Path]:
    """All figures of one study case (a ``CaseResult``) into ``out`` as ``fig<numbers>_<what><suffix>.png``.

    Rebuilds each state's scene (cheap) so the model's plots can draw clearance circles and
    Poincare sections, then draws every state of the case on the same axes.
    """
    from wearbench.model import SimulationResult, build_scene
    from wearbench.studies import plots

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    clear = result.run.clearances
    results = []
    for label, surfaces in result.run.states:
        scene = build_scene(bench, clearances=clear, surfaces=surfaces)
        summary = {**result.summaries[label], "label": label}
        results.append(SimulationResult(result.dynamics[label], summary, None, scene))
    makers = {"slider": plots.slider_figure, "contact_force": plots.contact_force_figure,
              "trajectory": plots.trajectory_figure, "poincare": plots.poincare_figure,
              "phase": plots.phase_figure}
    paths = []
    for what, make in makers.items():
        fig = make(results)
        path = out / f"fig{FIGURES[what][int(clearance_study)]}_{what}{suffix}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths
