"""The public API: ``import wearbench`` is the contract the documentation teaches."""

from __future__ import annotations

import inspect
import subprocess
import sys

import pytest

import wearbench

pytestmark = pytest.mark.no_kernels

CONTRACT = ["ArtefactError", "Assessment", "Bench", "BenchError", "Calibration", "Compute", "EnsembleSettings",
            "Estimate", "Estimator", "EstimatorDesign", "Identification", "Interval", "MeasuredSession", "Results",
            "SessionComparison", "SessionResult", "SessionSet", "SimulationError", "SimulationResult", "SpreadDesign", "Track",
            "build_ensembles", "build_estimator", "calibrate", "compare", "estimate", "identify", "load_bench",
            "load_ensembles", "load_estimator", "load_session", "record", "save_calibration", "simulate", "track",
            "write_report"]


def test_the_contract_is_all():
    """A name added to or removed from the API is a decision: this list changes with it."""
    assert wearbench.__all__ == CONTRACT


@pytest.mark.parametrize("name", CONTRACT)
def test_every_name_resolves_and_is_documented(name):
    value = getattr(wearbench, name)
    assert inspect.getdoc(value), f"wearbench.{name} has no docstring"
    if inspect.isfunction(value):
        assert all(p.annotation is not inspect.Parameter.empty for p in inspect.signature(value).parameters.values()
                   if p.kind not in (p.VAR_KEYWORD, p.VAR_POSITIONAL)), f"wearbench.{name}: untyped parameters"


def test_an_unknown_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'identfy'"):
        wearbench.identfy  # noqa: B018


def test_importing_wearbench_loads_no_library_layer():
    """``import wearbench`` (every command's first line) loads nothing heavy; names load on first use."""
    code = ("import sys, wearbench; print(sorted(m for m in sys.modules if m.startswith('wearbench.')));"
            "print('numpy' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split("\n")
    assert out[0] == "[]" and out[1] == "False"


def test_load_bench_takes_a_shipped_name_or_a_path(tmp_path):
    by_name = wearbench.load_bench("ninebar-testbed")
    assert by_name.name == "ninebar-testbed"
    assert wearbench.load_bench(by_name.path).name == by_name.name
    with pytest.raises(FileNotFoundError, match="shipped: .*ninebar-testbed"):
        wearbench.load_bench(tmp_path / "nothing.toml")


def test_results_make_a_table():
    """Results of several sessions are one DataFrame, a row per session, and JSON-able dicts."""
    from wearbench.validation.inference.identify import Identification

    def ident(name, p):
        return Identification(name, 20, {"new": p, "worn": 1 - p}, "new" if p > 0.9 else "undecided", max(p, 1 - p),
                              {}, {}, {}, {}, None, {}, {})

    table = wearbench.Results([ident("a", 0.95), ident("b", 0.5)]).to_dataframe()
    assert list(table.index) == ["a", "b"] and table.loc["a", "p[new]"] == 0.95
    assert table.loc["b", "verdict"] == "undecided"
    assert wearbench.Results([ident("a", 0.95)]).to_dict()[0]["posterior"] == {"new": 0.95, "worn": pytest.approx(0.05)}
