"""The tutorial "Your bench's first week" runs as written, then the Python how-to on its sessions.

The blocks come from the pages themselves (``docs/tools/tutorial.py``): every ``sh`` block of
``docs/tutorial/first-week.md`` in order, in one fresh folder, on the emulated bench, with the
settings the page prints (no option is rewritten: the page already asks for the emulated bench's
``speedup=inf`` and 20-cycle sessions, and uses the test bed's shipped ensembles and estimator).
Then every ``python`` block of ``docs/how-to/python.md`` runs in the same folder. Editing a page
changes what runs here. Beyond each command's success, what the page says happens is checked: the
files it says are written, the calibration used by the later commands, the cycles run read from
the sessions.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import tutorial

pytestmark = [pytest.mark.slow, pytest.mark.timeout(3600)]

DOCS = Path(__file__).resolve().parents[2] / "docs"
PAGE = DOCS / "tutorial" / "first-week.md"
PYTHON_HOWTO = DOCS / "how-to" / "python.md"


def test_the_blocks_are_found_on_the_page():
    """The extraction itself: the page's commands, in order, and its two emulator tables."""
    blocks = tutorial.blocks(PAGE)
    scripts = [b.text for b in blocks if b.kind == "sh"]
    assert scripts[0].startswith("wearbench bench copy ninebar-testbed mybench.toml")
    assert [b.name for b in blocks if b.kind == "file"] == ["wednesday.json", "friday.json"]
    commands = " ".join(scripts)
    for step in ("taptest", "record", "calibrate", "identify", "estimate", "track", "compare"):
        assert f"wearbench {step} " in commands, step
    assert [b.kind for b in tutorial.blocks(PYTHON_HOWTO)] and all(
        b.kind == "python" for b in tutorial.blocks(PYTHON_HOWTO))


def test_the_first_week_runs_as_written(tmp_path):
    week = tmp_path / "week"
    ran = tutorial.run(PAGE, week)
    for r in ran:
        for written in r.block.writes():
            assert (week / written).exists(), f"block at line {r.block.line} says it writes {written}"
    by_command = {r.block.text.split()[1]: r for r in ran if r.block.kind == "sh" and r.block.text.startswith("wearbench")}

    bench = (week / "mybench.toml").read_text()
    assert "latency = " in bench  # taptest --write-latency wrote the measured latency
    assert "calibration" in by_command["identify"].stdout  # calibrate's result is used, and said so
    [estimate] = json.loads((week / "wednesday-estimate.json").read_text())
    c = estimate["clearance"]
    assert c["lo90"] <= c["lo50"] <= c["median"] <= c["hi50"] <= c["hi90"]
    assert 0.2e-3 < c["median"] < 0.7e-3
    assert list((week / "wednesday-posterior").glob("posterior_*.png"))
    life = json.loads((week / "life.json").read_text())
    assert life["cycles_run"] == [0, 200000, 400000]  # read from the sessions (record --cycles-run)
    assert life["move"] is not None  # the shipped move was used
    report = week / "report"
    assert (report / "report.html").stat().st_size > 10_000
    assert [r["session"] for r in json.loads((report / "scores.json").read_text())["identification"]] == [
        "monday", "wednesday", "friday"]

    tutorial.run(PYTHON_HOWTO, week)  # the Python how-to, on the tutorial's sessions
