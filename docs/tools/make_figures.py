"""Make the documentation's figures (``docs/figures/*.png``), committed beside the pages.

    python docs/tools/make_figures.py [--skip-tutorial]

- ``slider-acceleration.png``: the shipped test bed's slider acceleration over one crank revolution
  (the second of two, from rest), with ideal joints and with 0.3 mm and 0.6 mm radial clearance at A
  and B, through ``import wearbench`` (load_bench, simulate).
- ``tutorial-*.png``: figures the tutorial itself writes. The tutorial's blocks are run in a scratch
  folder (``tutorial.run``, as the test does), then its figures are copied here, so each figure on a
  page is what the page's own commands produce.

The emulated sessions are chaotic, so a rerun gives other figures with the same statistics.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from pathlib import Path

DOCS = Path(__file__).resolve().parent.parent
ROOT = DOCS.parent
FIGURES = DOCS / "figures"
TUTORIAL = DOCS / "tutorial" / "first-week.md"
FROM_TUTORIAL = {  # figure here: file the tutorial writes
    "tutorial-posterior.png": "wednesday-posterior/posterior_wednesday.png",
    "tutorial-life.png": "life.png",
    "tutorial-band.png": "report/band_wednesday.png",
    "tutorial-posteriors.png": "report/posteriors.png",
}


def slider_acceleration(path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    import wearbench

    bench = wearbench.load_bench(ROOT / "hardware" / "benches" / "ninebar-testbed.toml")
    cases = [("ideal joints", None, "black", 1.6), ("0.3 mm clearance", 0.3e-3, "tab:blue", 0.8),
             ("0.6 mm clearance", 0.6e-3, "tab:red", 0.8)]
    fig, ax = plt.subplots(figsize=(8, 3.6), dpi=100)
    for label, clearance, color, width in cases:
        table = wearbench.simulate(bench, clearances={j: clearance for j in ("A", "B")}, revolutions=2).table
        second = table[table.t >= table.t.iloc[-1] / 2]
        angle = np.degrees(np.unwrap(second.theta_O1.to_numpy()) - second.theta_O1.iloc[0])
        ax.plot(angle, second.slider_acc, color=color, lw=width, label=label, zorder=3 if clearance is None else 2)
    ax.set_xlim(0, 360)
    ax.set_xlabel("crank angle in the second revolution (deg)")
    ax.set_ylabel("slider acceleration (m/s²)")
    ax.set_title(f"{bench.name}: the model at {bench.speed:.3g} rad/s, new surfaces", fontsize=10)
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def tutorial_figures() -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import tutorial

    with tempfile.TemporaryDirectory(prefix="wearbench-figures-") as tmp:
        tutorial.run(TUTORIAL, Path(tmp) / "week", echo=True)
        for name, made in FROM_TUTORIAL.items():
            shutil.copyfile(Path(tmp) / "week" / made, FIGURES / name)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--skip-tutorial", action="store_true", help="only the figures that do not run the tutorial")
    args = ap.parse_args()
    FIGURES.mkdir(exist_ok=True)
    slider_acceleration(FIGURES / "slider-acceleration.png")
    if not args.skip_tutorial:
        tutorial_figures()
    for path in sorted(FIGURES.glob("*.png")):
        print(f"{path.relative_to(ROOT)}: {path.stat().st_size // 1024} KiB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
