"""`wearbench ensemble --sensor-paths {drawn,none}` reaches the ensembles' settings, the saved file
and its content key (issue 31: drawn sensor paths could be switched off only from Python)."""

from __future__ import annotations

import numpy as np
import pytest
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.cli import main
from wearbench.validation.inference import ensemble as ensemble_module
from wearbench.validation.inference.ensemble import Ensemble, ensembles_key, load_ensembles
from wearbench.validation.inference.sensor_path import PathSpread

pytestmark = pytest.mark.no_kernels


def test_the_switch_sets_the_drawn_paths_of_the_saved_ensembles(tmp_path, monkeypatch, capsys):
    built = []

    def stand_in(bench, states, *, settings, **_):  # no realisations simulated: what the command asks for
        built.append(settings)
        rng = np.random.default_rng(0)
        m, c, p = settings.realisations, settings.cycles, settings.features.size
        return {s.name: Ensemble(s.name, settings, rng.normal(size=(m, c, p)), rng.normal(size=(m, c, settings.grid)),
                                 rng.normal(size=(m, c)), bench.speed) for s in states}

    monkeypatch.setattr(ensemble_module, "build_ensembles", stand_in)
    bench = load_bench(shipped_bench("ninebar-testbed"))
    files = {}
    for choice in ("drawn", "none", None):
        out = tmp_path / f"{choice}.npz"
        args = ["ensemble", "ninebar-testbed", "--realisations", "4", "--cycles", "2", "--out", str(out)]
        assert main(args + (["--sensor-paths", choice] if choice else [])) == 0
        files[choice] = out
    assert [s.sensor_paths for s in built] == [PathSpread(), None, PathSpread()]  # drawn is the default
    assert "sensor paths: none" in capsys.readouterr().out
    for choice, settings in zip(("drawn", "none"), built, strict=False):
        saved = load_ensembles(files[choice])
        assert next(iter(saved.values())).settings.sensor_paths == settings.sensor_paths
        # the content key tells the two apart: ensembles of one setting never stand for the other
        assert load_ensembles(files[choice], key=ensembles_key(bench, bench.states, bench.speed, settings)) is not None
    assert ensembles_key(bench, bench.states, bench.speed, built[0]) != ensembles_key(bench, bench.states,
                                                                                     bench.speed, built[1])
