"""`wearbench calibrate` on a bench whose accelerometer sits on a carriage with a 700 Hz mode (damping
0.05) the bench file does not know. The ensembles see every realisation through a drawn mount (0.3-3
kHz), so the uncalibrated verdict already names 0.6 mm new and finds it consistent (before drawn
paths: "none of the candidates", direction p 3e-8). Calibrated on one session of the same bench and
mount in a known state (0.3 mm new), 0.6 mm is named with p >= 0.99, consistent, and the result names
the calibration. Non-twin truths (seed 7000), shipped ensembles (no ensemble simulation). A calibrated
bench named right where the uncalibrated verdict was "none": ``test_calibrated.py`` (a sensor reading
half, outside the drawn paths)."""

import json

import pytest
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.cli import main
from wearbench.compute.options import QUIET
from wearbench.synthetic.truths import record_state, slug
from wearbench.validation.inference.ensemble import (
    EnsembleSettings,
    build_ensembles,
    ensembles_key,
    save_ensembles,
)

pytestmark = pytest.mark.slow

MOUNT = {"resonance": "700 Hz", "damping": 0.05}


@pytest.fixture(scope="module")
def sessions(tmp_path_factory):
    bench = load_bench(shipped_bench("ninebar-testbed"))
    out = tmp_path_factory.mktemp("mount")
    paths = {}
    for name in ("0.3 mm new", "0.6 mm new"):
        state = next(s for s in bench.states if s.name == name)
        paths[name] = out / f"{slug(name)}.mcap"
        record_state(bench, state, 7000, paths[name], backend="sim", cycles=11, revolutions=14, accelerometer=MOUNT)
    ens = build_ensembles(bench, bench.states, compute=QUIET)  # shipped: no simulation
    saved = save_ensembles(ens, out / "e.npz", key=ensembles_key(bench, bench.states, bench.speed, EnsembleSettings()),
                           bench=bench, states=bench.states)
    return paths, saved


def test_a_mount_inside_the_drawn_paths_is_named_uncalibrated_and_calibrated(sessions, tmp_path, capsys):
    paths, saved = sessions
    exact = tmp_path / "exact.json"
    assert main(["identify", str(paths["0.6 mm new"]), "--ensembles", str(saved), "--calibration", "none",
                 "--json", str(exact)]) == 0
    row = json.loads(exact.read_text())[0]
    assert row["verdict"] == "0.6 mm new" and row["p_value"]["0.6 mm new"] > 0.01, row
    assert main(["calibrate", str(paths["0.3 mm new"]), "--state", "0.3 mm new", "--ensembles", str(saved)]) == 0
    out = capsys.readouterr().out
    assert "calibration: " in out and "gain" in out
    assert main(["calibrate", str(paths["0.3 mm new"]), "--state", "0.3 mm new", "--ensembles", str(saved)]) == 2
    assert "--force" in capsys.readouterr().err
    cal = tmp_path / "cal.json"
    assert main(["identify", str(paths["0.6 mm new"]), "--ensembles", str(saved), "--json", str(cal)]) == 0
    row = json.loads(cal.read_text())[0]
    assert row["posterior"]["0.6 mm new"] >= 0.99 and row["p_value"]["0.6 mm new"] > 0.01, row
    assert row["sensor_path"].startswith("calibration") and any("sensor path: calibration" in n for n in row["notes"])


def test_a_calibration_its_sessions_doubt_is_stored_only_with_force(sessions, tmp_path, capsys):
    """A 0.6 mm session given as the known state 0.3 mm new: identification (the unmeasured mount's
    prior) names 0.6 mm new, so calibrate refuses, saying why, before storing anything; --force stores
    it with the doubt said and kept in the file. The same recording given twice is refused too."""
    paths, saved = sessions
    store = tmp_path / "calibrations"
    wrong = ["calibrate", str(paths["0.6 mm new"]), "--state", "0.3 mm new", "--ensembles", str(saved),
             "--dir", str(store)]
    assert main(wrong) == 2
    err = capsys.readouterr().err
    assert "is identified as '0.6 mm new'" in err and "is the bench really in '0.3 mm new'?" in err and "--force" in err
    assert not store.exists()
    assert main([*wrong, "--force"]) == 0
    assert "warning: session 0p6_mm_new is identified as '0.6 mm new'" in capsys.readouterr().out
    (stored,) = store.glob("*.json")
    assert any("identified as '0.6 mm new'" in d for d in json.loads(stored.read_text())["doubts"])
    twice = ["calibrate", str(paths["0.3 mm new"]), str(paths["0.3 mm new"]), "--state", "0.3 mm new",
             "--ensembles", str(saved), "--dir", str(tmp_path / "twice")]
    assert main(twice) == 2
    assert "the same recording as 0p3_mm_new" in capsys.readouterr().err
