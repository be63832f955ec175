"""`wearbench calibrate` on a bench whose accelerometer sits on a carriage with a 700 Hz mode the
bench file does not know: taken as exact, the sensor path makes a 0.6 mm session "none of the
candidates" and the diagnosis blames the path; calibrated on one session of the same bench and
mount in a known state (0.3 mm new), the session is named right and the result names the
calibration. Non-twin truths (seed 7000), shipped ensembles (no ensemble simulation)."""

import json

import pytest
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.cli import main
from wearbench.cli.demo import record_state, slug
from wearbench.validation.ensemble import (
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
    ens = build_ensembles(bench, bench.states, progress=None)  # shipped: no simulation
    saved = save_ensembles(ens, out / "e.npz", key=ensembles_key(bench, bench.states, bench.speed, EnsembleSettings()))
    return paths, saved


def test_calibration_names_a_session_the_exact_path_cannot_explain(sessions, tmp_path, capsys):
    paths, saved = sessions
    exact = tmp_path / "exact.json"
    assert main(["identify", str(paths["0.6 mm new"]), "--ensembles", str(saved), "--calibration", "none",
                 "--json", str(exact)]) == 0
    row = json.loads(exact.read_text())[0]
    assert row["verdict"] == "none of the candidates", row["posterior"]
    assert row["diagnosis"]["sensor_path_explains"], row["diagnosis"]
    assert main(["calibrate", str(paths["0.3 mm new"]), "--state", "0.3 mm new", "--ensembles", str(saved)]) == 0
    out = capsys.readouterr().out
    assert "calibration: " in out and "gain" in out
    assert main(["calibrate", str(paths["0.3 mm new"]), "--state", "0.3 mm new", "--ensembles", str(saved)]) == 2
    assert "--replace" in capsys.readouterr().err
    cal = tmp_path / "cal.json"
    assert main(["identify", str(paths["0.6 mm new"]), "--ensembles", str(saved), "--json", str(cal)]) == 0
    row = json.loads(cal.read_text())[0]
    assert row["verdict"] == "0.6 mm new", row["posterior"]
    assert row["sensor_path"].startswith("calibration") and any("sensor path: calibration" in n for n in row["notes"])
