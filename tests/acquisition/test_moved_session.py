"""Issue 25, item 10: a bench file naming worn surfaces by a relative path (the shipped test bed
does). A session recorded with it keeps its bench when moved (it carries the named files), and the
README's recipe for starting a bench of one's own (`wearbench bench copy ninebar-testbed ...`) gives
a file that loads and records."""

from __future__ import annotations

import json
import shutil

import numpy as np
from wearbench.acquisition.session_file import read_session
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.cli import main

from .conftest import FAST, HARMONIC


def test_a_moved_session_keeps_its_bench_and_the_copy_recipe_works(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("WEARBENCH_CACHE", str(tmp_path / "cache"))
    mine = tmp_path / "lab" / "mybench.toml"
    assert main(["bench", "copy", "ninebar-testbed", str(mine)]) == 0
    original = load_bench(shipped_bench("ninebar-testbed"))
    copy = load_bench(mine)
    assert [s.name for s in copy.states] == [s.name for s in original.states]
    for a, b in zip(original.states, copy.states, strict=True):
        for joint in a.surfaces:
            assert b.surfaces[joint].read_bytes() == a.surfaces[joint].read_bytes()
            assert b.surfaces[joint].is_relative_to(mine.parent)
    assert main(["bench", "copy", "ninebar-testbed", str(mine)]) == 2  # the policy: not without --force
    assert "already exists" in capsys.readouterr().err
    config = tmp_path / "emulator.json"
    config.write_text(json.dumps(HARMONIC))
    out = tmp_path / "lab" / "s.mcap"
    assert main(["record", str(mine), "--backend", "sim", "--option", "speedup=inf", "--option", f"config={config}",
                 "--speed", f"{FAST}", "--cycles", "2", "--out", str(out)]) == 0
    shutil.rmtree(tmp_path / "lab" / "worn")  # the lab moves on: the bench's files are gone ...
    mine.rename(tmp_path / "lab" / "renamed.toml")
    moved = tmp_path / "elsewhere" / "s.mcap"  # ... and the session is moved
    moved.parent.mkdir()
    out.rename(moved)
    s = read_session(moved)
    assert s.bench is not None, s.problem
    assert [st.name for st in s.bench.states] == [st.name for st in original.states]
    worn = next(st for st in s.bench.states if st.surfaces)
    joint, path = next(iter(worn.surfaces.items()))
    original_file = next(st for st in original.states if st.name == worn.name).surfaces[joint]
    assert np.array_equal(np.load(path)["bearing"], np.load(original_file)["bearing"])
