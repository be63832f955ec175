"""The first run of a model version says that its kernels are compiling (minutes of silence otherwise)."""

from __future__ import annotations

from wearbench.bench.load import load_bench, resolve_bench
from wearbench.cli.progress import COMPILING, note_compiling
from wearbench.model import build_scene, jit_cache, simulate


def test_a_cold_cache_is_announced_and_a_warm_one_is_not(tmp_path, monkeypatch, capsys):
    scene = build_scene(load_bench(resolve_bench("slider-crank")))  # a clearance joint at S
    simulate(scene, revolutions=0.05)  # compiled (or loaded): the real cache holds the loop now
    assert note_compiling() is False
    assert capsys.readouterr().err == ""
    monkeypatch.setattr(jit_cache, "numba_cache_dir", lambda: tmp_path / "empty")  # as after a model change
    (tmp_path / "empty").mkdir()
    assert note_compiling() is True
    assert capsys.readouterr().err == COMPILING + "\n"
