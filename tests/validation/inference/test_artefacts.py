"""Keyed artefacts: every file says what it is and what it is for, a wrong one is named in one line,
and the shipped ones are the package's."""

from __future__ import annotations

import json

import numpy as np
import pytest
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.cli import main
from wearbench.validation.estimation.estimate import load_estimator, save_estimator
from wearbench.validation.inference import artefacts
from wearbench.validation.inference.ensemble import load_ensembles

pytestmark = pytest.mark.no_kernels

BENCH = load_bench(shipped_bench("ninebar-testbed"))
SHIPPED_ENSEMBLES = artefacts.shipped_path("ensembles", BENCH.name)
SHIPPED_ESTIMATOR = artefacts.shipped_path("estimator", BENCH.name)


def test_the_shipped_files_name_their_bench_speed_and_sensor_path():
    for kind, path in (("ensembles", SHIPPED_ENSEMBLES), ("estimator", SHIPPED_ESTIMATOR)):
        about = artefacts.read_about(path, kind)
        assert about.bench == BENCH.name and about.speed == pytest.approx(BENCH.speed)
        assert "drawn per realisation" in about.sensor_path
        about.check(path, bench=BENCH, speed=BENCH.speed)  # fits the bench it was built for


def test_a_file_of_another_kind_is_named_in_one_line(tmp_path):
    with pytest.raises(artefacts.ArtefactError, match=r"is an ensembles file, not an estimator$"):
        load_estimator(SHIPPED_ENSEMBLES)
    with pytest.raises(artefacts.ArtefactError, match=r"is an estimator, not an ensembles file$"):
        load_ensembles(SHIPPED_ESTIMATOR)
    calibration = tmp_path / "c.json"
    calibration.write_text(json.dumps({"about": {**json.loads(artefacts.About(
        "calibration", "k", "b", "", float("nan"), "x").to_json())}, "key": "k"}))
    with pytest.raises(artefacts.ArtefactError, match=r"c.json is a calibration, not an estimator$"):
        load_estimator(calibration)
    other = tmp_path / "other.npz"
    np.savez(other, x=np.arange(3))
    with pytest.raises(artefacts.ArtefactError, match=r"other.npz: not an estimator .*no 'about' record"):
        load_estimator(other)
    legacy = tmp_path / "legacy.npz"
    np.savez(legacy, key=np.array("k"), meta=np.array("{}"), features=np.zeros(1))
    with pytest.raises(artefacts.ArtefactError, match="an estimator written by a wearbench before .*build it again"):
        load_estimator(legacy)
    with pytest.raises(FileNotFoundError, match="no such file; expected an estimator"):
        load_estimator(tmp_path / "missing.npz")


def test_an_artefact_of_another_bench_or_speed_is_refused_naming_both(tmp_path):
    about = artefacts.read_about(SHIPPED_ESTIMATOR, "estimator")
    with pytest.raises(artefacts.ArtefactError, match=r"built for bench 'ninebar-testbed'; session s recorded on "
                                                      r"bench 'fourbar'"):
        about.check(SHIPPED_ESTIMATOR, bench=load_bench(shipped_bench("fourbar")), session="s")
    with pytest.raises(artefacts.ArtefactError, match=r"built at 6.28319 rad/s; session s commanded at 12.5664 rad/s"):
        about.check(SHIPPED_ESTIMATOR, bench=BENCH, speed=4 * np.pi, session="s")


def test_ship_refuses_in_an_installed_package_and_over_a_shipped_file_without_force(monkeypatch, capsys):
    """Both before any simulation: --ship in an installed package never writes (a reinstall would be the
    only way back), and in a source checkout it replaces a shipped file only with --force."""
    before = SHIPPED_ESTIMATOR.read_bytes()
    assert main(["estimator", BENCH.name, "--ship", "--realisations", "4"]) == 2
    err = capsys.readouterr().err
    assert "--ship:" in err and "holds the shipped estimator of bench 'ninebar-testbed'" in err and "--force" in err
    monkeypatch.setattr(artefacts, "source_checkout", lambda: None)
    for command in (["estimator", BENCH.name, "--ship", "--force", "--realisations", "4"],
                    ["ensemble", BENCH.name, "--ship", "--force", "--realisations", "4"]):
        assert main(command) == 2
        assert "not a source checkout" in capsys.readouterr().err
    assert SHIPPED_ESTIMATOR.read_bytes() == before


def test_a_hand_made_estimator_names_no_bench_and_reads_back(tmp_path):
    from wearbench.validation.estimation.estimate import Estimator

    from ..estimation.test_estimate import DESIGN

    est = Estimator("synthetic", "k", DESIGN, np.zeros((5, 4, 3, 2, 4)), np.zeros((5, 4)), 2 * np.pi)
    back = load_estimator(save_estimator(est, tmp_path / "e.npz"))
    assert back.about.bench_key == "" and back.about.bench == "synthetic" and back.speed == est.speed
    back.about.check(tmp_path / "e.npz", bench=BENCH)  # no bench key: tied to no bench
