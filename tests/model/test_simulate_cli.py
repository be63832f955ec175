"""`wearbench simulate`: unit-bearing options, JSON summary, table and figures written."""

from __future__ import annotations

import json

import pandas as pd
from wearbench.cli import main


def test_simulate_cli_writes_table_plots_and_json(tmp_path, capsys):
    out = tmp_path / "run.parquet"
    code = main(["simulate", "ninebar", "--clearance", "A=0.6mm,B=0.3mm", "--speed", "-5pi",
                 "--t-end", "20ms", "--out", str(out), "--plots", str(tmp_path / "figs"), "--json"])
    assert code == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["speed"] == -5 * 3.141592653589793
    assert set(summary["peak_fn"]) == {"A", "B"} and summary["dof"] == 4
    table = pd.read_parquet(out)
    for col in ("t", "theta_O1", "theta_O4", "slider_pos", "slider_vel", "slider_acc", "A_ex", "A_ey", "A_pen",
                "A_fn", "A_ft", "A_vn", "A_vt", "B_fn"):
        assert col in table
    assert (tmp_path / "figs" / "trajectory.png").exists() and (tmp_path / "figs" / "slider.svg").exists()


def test_simulate_cli_rpm_and_ideal_joint(capsys):
    assert main(["simulate", "slider-crank", "--clearance", "S=ideal", "--speed", "300rpm",
                 "--revolutions", "1"]) == 0
    assert "kinematics" in capsys.readouterr().out


def test_simulate_cli_bad_clearance_is_one_clear_error(capsys):
    assert main(["simulate", "ninebar", "--clearance", "Z=0.6mm"]) == 2
    assert "no clearance joint" in capsys.readouterr().err
