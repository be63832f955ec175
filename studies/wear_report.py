"""Files and figures of a wear run: surfaces (.npz + CSV), a JSON summary, and the paper's
figures 6-8 analogues (depth against angle; polar bearing and journal surfaces).

Imports matplotlib (Agg), pandas and the wear-stage dataclasses; not the simulator.
"""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from wearbench.model.surfaces import JointSurfaces
from wearbench.model.wear_stages import WearRun, joint_summary

__all__ = ["convergence_markdown", "load_states", "plot_depths", "plot_polar", "run_summary", "write_run"]


def run_summary(run: WearRun) -> dict:
    """JSON-ready summary: settings, and per stage the simulation's peaks, wall time and per joint
    max depth, its angle and wear zones of bearing and journal, worn and Archard volumes."""
    plan = run.plan
    out = {
        "bench": run.bench_name, "speed_rad_s": run.speed, "clearances_m": run.clearances,
        "plan": {"stages": plan.stages, "stage_cycles": plan.stage_cycles, "update_depth_m": plan.depth_cap,
                 "update_revolutions": plan.update_revolutions, "settle_revolutions": plan.settle,
                 "pressure_change": plan.pressure_change, "method": plan.method,
                 "sliding": plan.sliding, "footprint": plan.footprint, "split": plan.split},
        "simulated_revolutions": run.revolutions,
        "stages": [],
    }
    for st in run.stages:
        sim = st.sim_summary
        out["stages"].append({
            "index": st.index, "label": st.label, "cycles": next(iter(st.surfaces.values())).cycles,
            "wall_time_s": round(st.wall_time, 3), "updates": st.updates, "revolutions": st.revolutions,
            "simulated_on": next(iter(st.start.values())).label,
            "sim": {k: sim.get(k) for k in ("method", "steps", "rejected_steps", "peak_fn", "wall_time_s")},
            "joints": {j: {**joint_summary(s, clearance=run.clearances[j]), "worn_volume_m3": st.volume[j],
                           "archard_volume_m3": st.archard_volume[j]} for j, s in st.surfaces.items()},
        })
    return out


def convergence_markdown(rows: list[dict]) -> str:
    """The refinement table of :func:`~wearbench.model.wear_stages.convergence` as Markdown: per
    refinement and joint the max and reachable depths (um) of bearing and journal, the worn volume
    (mm^3), updates, simulated revolutions, wall time, and the largest change against the coarser row."""
    head = ("| refinement | cap (um) | joint | bearing max | bearing reach | journal max | journal reach | "
            "volume (mm^3) | updates | revolutions | wall (s) | change vs coarser |")
    lines = [head, "|" + "---|" * 12]
    for r in rows:
        changes = [r[k] for k in r if k.endswith("_change") and r[k] == r[k]]
        ch = f"{max(changes):.1%}" if changes else "-"
        lines.append(f"| {r['refinement']:g} | {r['depth_cap_m'] * 1e6:.3g} | {r['joint']} | "
                     f"{r['bearing_max_m'] * 1e6:.1f} | {r['bearing_reachable_m'] * 1e6:.1f} | "
                     f"{r['journal_max_m'] * 1e6:.1f} | {r['journal_reachable_m'] * 1e6:.1f} | "
                     f"{r['volume_m3'] * 1e9:.4g} | {r['updates']} | {r['revolutions']:g} | {r['wall_time_s']:g} | {ch} |")
    return "\n".join(lines)


def _depth_table(run: WearRun) -> pd.DataFrame:
    frames = []
    for j in run.clearances:
        for side in ("bearing", "journal"):
            n = getattr(run.initial[j], side).size
            cols = {"joint": j, "surface": side, "region": np.arange(n),
                    "angle_deg": (np.arange(n) + 0.5) * 360.0 / n}
            for label, states in run.states:
                cols[f"{label} [m]"] = getattr(states[j], side)
            frames.append(pd.DataFrame(cols))
    return pd.concat(frames, ignore_index=True)


def write_run(run: WearRun, out: str | Path, *, plots: bool = True) -> dict[str, Path]:
    """Write ``out/surfaces/<joint>_<k>.npz`` (k = 0 initial, 1.. stages), ``out/depths.csv``,
    ``out/summary.json`` and, with ``plots``, ``out/wear_depth.png`` and ``out/surface_<joint>.png``.
    Returns the paths by kind."""
    out = Path(out)
    (out / "surfaces").mkdir(parents=True, exist_ok=True)
    paths: dict[str, Path] = {}
    for k, (_, states) in enumerate(run.states):
        for j, s in states.items():
            paths[f"{j}_{k}"] = s.save(out / "surfaces" / f"{j}_{k}.npz")
    paths["csv"] = out / "depths.csv"
    _depth_table(run).to_csv(paths["csv"], index=False, float_format="%.6e")
    paths["summary"] = out / "summary.json"
    paths["summary"].write_text(json.dumps(run_summary(run), indent=2, default=float) + "\n")
    if plots:
        paths["depth_plot"] = plot_depths(run, out / "wear_depth.png")
        for j in run.clearances:
            paths[f"polar_{j}"] = plot_polar(run, j, out / f"surface_{j}.png")
    return paths


def plot_depths(run: WearRun, path: str | Path) -> Path:
    """Depth against body-frame angle per joint (rows), bearing and journal (columns), one line per
    stage, like the paper's Fig. 6 (and Fig. 18)."""
    joints = list(run.clearances)
    fig, axes = plt.subplots(len(joints), 2, figsize=(11, 2.8 * len(joints)), squeeze=False)
    for row, j in zip(axes, joints, strict=True):
        for ax, side in zip(row, ("bearing", "journal"), strict=True):
            for label, states in run.states[1:]:
                d = getattr(states[j], side)
                ax.plot((np.arange(d.size) + 0.5) * 360.0 / d.size, d * 1e6, lw=1, label=label)
            ax.set(title=f"clearance {j}: {side}", xlabel="angle in body frame [deg]", ylabel="wear depth [um]",
                   xlim=(0, 360))
            ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path)


def plot_polar(run: WearRun, joint: str, path: str | Path, exaggerate: float | None = None) -> Path:
    """Bearing and journal profiles after each stage, depths magnified so they show (Figs. 7-8).

    Radius drawn: R + m d (bearing) and R - m d (journal) on a nominal radius 1 for both, with
    magnification m chosen so the deepest wear spans 0.3 of the radius unless given.
    """
    states = run.states
    peak = max(max(s[joint].max_depth) for _, s in states) or 1.0
    m = exaggerate or 0.3 / peak
    fig, axes = plt.subplots(1, 2, subplot_kw={"projection": "polar"}, figsize=(9, 4.5))
    for ax, side, sign in ((axes[0], "bearing", 1.0), (axes[1], "journal", -1.0)):
        for label, st in states:
            d = getattr(st[joint], side)
            phi = (np.arange(d.size + 1) % d.size + 0.5) * 2 * np.pi / d.size
            ax.plot(phi, 1.0 + sign * m * d[np.arange(d.size + 1) % d.size], lw=1, label=label)
        ax.set_title(f"{joint} {side} (depth x{m:.3g})", fontsize=9)
        ax.set_rticks([])
    axes[1].legend(fontsize=7, loc="lower left", bbox_to_anchor=(0.9, 0.0))
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path)


def load_states(out: str | Path) -> dict[str, list[JointSurfaces]]:
    """Read back ``out/surfaces/*.npz`` written by :func:`write_run`: {joint: [state 0, 1, ...]}."""
    found: dict[str, dict[int, JointSurfaces]] = {}
    for p in sorted(Path(out, "surfaces").glob("*_*.npz")):
        j, k = p.stem.rsplit("_", 1)
        found.setdefault(j, {})[int(k)] = JointSurfaces.load(p)
    return {j: [d[k] for k in sorted(d)] for j, d in found.items()}
