"""Sessions recorded before the protobuf layout (``data/session_layout1.mcap``, see data/README.md)
stay readable: read_session gives the samples the file holds (decoded here independently from its
JSON), and `wearbench inspect`, `recover` and `compare` work on it; `recover` rewrites it in the
current layout with every sample as it was."""

from __future__ import annotations

import base64
import json
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from wearbench.acquisition.recover import recover
from wearbench.acquisition.session_file import read_session
from wearbench.cli import main

LAYOUT1 = Path(__file__).with_name("data") / "session_layout1.mcap"


def _raw(topic: str) -> list[dict]:
    with open(LAYOUT1, "rb") as fh:
        return [json.loads(m.data) for _, _, m in make_reader(fh).iter_messages(topics=[topic])]


def test_read_layout1():
    s = read_session(LAYOUT1)
    assert s.finished and s.problem is None and s.metadata["session"]["operator"] == "layout-1 fixture"
    acc = np.concatenate([np.frombuffer(base64.b64decode(m["samples"]), "<f4")
                          for m in sorted(_raw("/acceleration"), key=lambda m: m["sequence"])])
    assert len(acc) == 2600
    np.testing.assert_array_equal(s.acceleration.acc.to_numpy(np.float32), acc)
    assert not s.acceleration.clipped.any()
    counts = np.concatenate([np.frombuffer(base64.b64decode(m["counts"]), "<i4")
                             for m in sorted(_raw("/encoder"), key=lambda m: m["sequence"])])
    assert len(s.encoder) == len(counts) == 250 and s.encoder["index"].sum() == sum(
        len(m["index_at"]) for m in _raw("/encoder"))
    assert list(s.events.kind) == [e["kind"] for e in _raw("/events")]
    assert len(s.motor) == len(_raw("/motor/state")) and s.motor.fault.isna().all()


def test_inspect_and_recover_layout1(tmp_path, capsys):
    assert main(["inspect", str(LAYOUT1)]) == 0
    acc = next(line for line in capsys.readouterr().out.splitlines() if line.strip().startswith("/acceleration"))
    assert acc.split()[1:3] == ["13", "2600"]
    fixed = tmp_path / "recovered.mcap"
    r = recover(LAYOUT1, fixed)
    assert r.was_finished and r.upgraded
    assert r.messages == 13 + 25 + len(_raw("/motor/state")) + 4 + len(_raw("/events"))
    with open(fixed, "rb") as fh:
        summary = make_reader(fh).get_summary()
    assert {c.message_encoding for c in summary.channels.values()} == {"protobuf"}
    assert {s.name for s in summary.schemas.values()} >= {"wearbench.AccelerationBlock", "foxglove.Log"}
    old, new = read_session(LAYOUT1), read_session(fixed)
    for frame in ("acceleration", "encoder", "motor"):
        a, b = getattr(old, frame), getattr(new, frame)
        assert list(a.columns) == list(b.columns)
        for column in a.columns:
            np.testing.assert_array_equal(b[column].to_numpy(), a[column].to_numpy(), err_msg=f"{frame}.{column}")
    assert list(new.events.kind) == [*old.events.kind, "recovered"]
    np.testing.assert_allclose(new.events.time.iloc[:-1], old.events.time, atol=1e-9)
    assert new.metadata["recovery"]["layout"] == "rewritten from layout 1 (JSON)"


@pytest.mark.slow
def test_compare_layout1(tmp_path, capsys):
    from wearbench.validation.comparison.theory import simulate_theory

    s = read_session(LAYOUT1)
    theory = tmp_path / "theory.parquet"
    simulate_theory(s.bench, speed=62.0, revolutions=2).to_parquet(theory)
    assert main(["compare", str(LAYOUT1), "--out", str(tmp_path / "report"), "--theory", str(theory),
                 "--cycles", "1"]) == 0
    scores = json.loads((tmp_path / "report" / "scores.json").read_text())
    assert scores["sessions"][0]["windows"], scores["sessions"][0]
