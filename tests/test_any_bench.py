"""Issue 44, item 5: every shipped bench, and a lab's own four-bar (``tests/data/lab-fourbar.toml``:
links 20 % longer, 1.5 Hz, the clearance at the crank pin, the accelerometer on the coupler), goes
through record -> identify -> estimate (-> track) at reduced size, end to end on the command line.

Sessions are emulated non-twin truths (``synthetic.truths.record_state``: a bench drawn from the
bench file's tolerances with a seed the theory does not use, through the emulator's sensor chain).
The test bed's shipped ensembles and estimator fit its sessions, so nothing is built for it; the
other benches build small theory (``--small``), which each command prices before it starts."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.cli import main
from wearbench.synthetic.truths import record_state, slug

LAB = Path(__file__).parent / "data" / "lab-fourbar.toml"


def record(bench, states, seed, where: Path, cycles: int = 10) -> list[str]:
    out = []
    for state in states:
        path = where / f"{slug(state.name)}_{seed}.mcap"
        record_state(bench, state, seed, path, backend="sim", cycles=cycles, revolutions=14)
        out.append(str(path))
    return out


def clearance(state) -> float:
    return next(iter(state.clearances.values()))


def identify_and_estimate(paths, states, tmp_path, capsys, *size) -> list[dict]:
    capsys.readouterr()
    assert main(["identify", *paths, *size, "--workers", "0", "--estimate", "--calibration", "none",
                 "--json", str(tmp_path / "r.json")]) == 0
    rows = json.loads((tmp_path / "r.json").read_text())
    for row, state in zip(rows, states, strict=True):
        assert max(row["posterior"], key=row["posterior"].get) == state.name, row["posterior"]
        assert not row["flat"] and row["verdict"] != "the features cannot tell the candidates apart"
        assert row["estimate"]["explains"] and not row["estimate"]["flat"], row["estimate"]["notes"]
    medians = [row["estimate"]["clearance"]["median"] for row in rows]
    assert medians == sorted(medians), medians  # the looser joint is estimated looser
    return rows


@pytest.mark.slow
@pytest.mark.parametrize("name", ["ninebar-testbed", "fourbar", "slider-crank"])
def test_every_shipped_bench_records_identifies_and_estimates(name, tmp_path, capsys):
    bench = load_bench(shipped_bench(name))
    states = sorted(bench.states, key=clearance)[:1] + sorted(bench.states, key=clearance)[-1:]
    paths = record(bench, states, 501, tmp_path)
    size = [] if name == "ninebar-testbed" else ["--small"]
    rows = identify_and_estimate(paths, states, tmp_path, capsys, *size)
    err = capsys.readouterr().err
    if name == "ninebar-testbed":  # its shipped theory fits: nothing is built, nothing announced
        assert "realisations, about" not in err
        for row, state in zip(rows, states, strict=True):
            c = row["estimate"]["clearance"]
            assert c["lo90"] <= clearance(state) <= c["hi90"], c
    else:
        assert "theory ensembles: 16 realisations, about" in err and "estimator: 3 wear runs and 27 realisations" in err


@pytest.mark.slow
def test_a_labs_own_four_bar_goes_through_record_identify_estimate_and_track(tmp_path, capsys):
    bench = load_bench(LAB)
    assert (bench.speed, [j.name for j in bench.clearance_joints]) == (pytest.approx(3 * 3.141592653589793), ["P"])
    states = sorted(bench.states, key=clearance)
    paths = record(bench, states, 501, tmp_path)
    identify_and_estimate(paths, states, tmp_path, capsys, "--small")
    # one bench (one seed) over its life: new joints, recorded as if after 0 and 200,000 cycles
    life = []
    for k in range(2):
        (tmp_path / f"life{k}").mkdir()
        life += record(bench, states[:1], 502, tmp_path / f"life{k}", cycles=10 + 2 * k)
    assert main(["track", *life, "--cycles-run", "0,200000", "--small", "--workers", "0", "--calibration", "none",
                 "--no-move", "--json", str(tmp_path / "t.json")]) == 0
    track = json.loads((tmp_path / "t.json").read_text())
    c = track["clearance"]  # a small design's intervals are narrow: its median near the truth, not more
    assert c["lo90"] < c["median"] < c["hi90"] and abs(c["median"] - clearance(states[0])) < 0.1e-3, c
    assert track["factor"]["median"] < 1.0  # new joints all along: less wear than the bench file's rate
