"""Session files in the readers other tools use: @mcap/core's indexed reader (what Foxglove opens
files with) decodes every message with protobufjs from the schema in the file and gets the same
samples as our reader; the plotted fields are numbers or numeric arrays. A layout-1 file (no
message indexes) fails that reader, as it did in Foxglove, and passes once recovered."""

from __future__ import annotations

import math
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from wearbench.acquisition.backends import open_rig
from wearbench.acquisition.drivers import ACCELERATION, ENCODER
from wearbench.acquisition.recorder import Recorder
from wearbench.acquisition.recover import recover
from wearbench.acquisition.session import SessionPlan
from wearbench.acquisition.session_file import blocks, read_session, scan_mcap
from wearbench.acquisition.session_writer import SessionWriter
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.testing import mcap_readers

pytestmark = pytest.mark.no_kernels

LAYOUT1 = Path(__file__).parents[1] / "acquisition" / "data" / "session_layout1.mcap"
PLOTTED = {"/acceleration": {"acceleration": "array", "clipped": "number", "device_time": "number"},
           "/encoder": {"counts": "array", "crank_angle": "array", "cycle": "array"},
           "/motor/state": {"angle": "number", "speed": "number", "counts": "number", "enabled": "number"},
           "/motor/command": {"speed": "number", "acceleration": "number"},
           "/events": {"level": "number", "message": "string", "name": "string"}}


@pytest.fixture(scope="module")
def sessions(tmp_path_factory):
    """A finished sim session, and the recovery of a copy cut in its last chunk."""
    tmp = tmp_path_factory.mktemp("interop")
    bench = load_bench(shipped_bench("ninebar-testbed"))
    rig = open_rig(bench, "sim", {"speedup": math.inf, "config": {"signal": "harmonic", "cache": False}})
    finished = tmp / "finished.mcap"
    try:
        writer = SessionWriter(finished, chunk_size=16 << 10)  # several chunks to cut between
        assert Recorder(rig, bench, SessionPlan(speed=62.0, cycles=5), finished, writer=writer).run().completed
    finally:
        rig.close()
    cut = tmp / "cut.mcap"
    data = finished.read_bytes()
    with open(finished, "rb") as fh:
        last = make_reader(fh).get_summary().chunk_indexes[-1]
    cut.write_bytes(data[: last.chunk_start_offset + last.chunk_length // 2])
    recovered = tmp / "recovered.mcap"
    recover(cut, recovered)
    return finished, recovered


def _node(paths, folder):
    return {Path(r["path"]).name: r for r in mcap_readers.read_with_node(list(paths), folder)}


def test_indexed_reader_reads_what_we_wrote(sessions, node_readers):
    results = _node(sessions, node_readers)
    for path in sessions:
        r = results[path.name]
        assert r["ok"], r.get("error")
        scan = scan_mcap(path)
        assert r["messageCount"] == len(scan.messages) and r["chunks"] == scan.chunks
        assert {t: v["messages"] for t, v in r["topics"].items()} == mcap_readers.read_with_python(path)
        for topic, fields in PLOTTED.items():
            got = {f: r["topics"][topic]["fields"][f]["kind"] for f in fields}
            assert got == fields, f"{path.name} {topic}"
        # protobufjs decodes the same samples as our reader, from the schema in the file
        acc = np.concatenate([b.samples for b in blocks(scan, ACCELERATION)]).astype(np.float64)
        f = r["topics"]["/acceleration"]["fields"]["acceleration"]
        assert f["count"] == acc.size and f["sum"] == pytest.approx(acc.sum(), abs=1e-9 * np.abs(acc).sum())
        counts = np.concatenate([b.samples for b in blocks(scan, ENCODER)]).astype(np.int64)
        f = r["topics"]["/encoder"]["fields"]["counts"]
        assert f["count"] == counts.size and f["sum"] == counts.sum()
    s = read_session(sessions[0])
    assert r["topics"]["/events"]["messages"] >= 3 and s.events.kind.iloc[0] == "phase"


def test_layout1_needs_recovery_for_the_indexed_reader(tmp_path, node_readers):
    old = tmp_path / "layout1.mcap"
    shutil.copyfile(LAYOUT1, old)
    fixed = tmp_path / "layout1-recovered.mcap"
    recover(old, fixed)
    results = _node([old, fixed], node_readers)
    assert not results[old.name]["ok"]  # the files labs recorded before message indexes
    assert "message index" in results[old.name]["error"]
    assert results[fixed.name]["ok"], results[fixed.name].get("error")
    assert mcap_readers.read_with_python(fixed) == {t: v["messages"] for t, v in results[fixed.name]["topics"].items()}
    old.unlink()  # the suite-wide check would flag it: it is the layout this issue replaces


def test_the_order_check_catches_a_message_logged_back_in_time():
    """The suite's log-time check (mcap doctor --strict-message-order) fails a file whose messages
    go back in time across channels; written outside the run's temporary folder, whose files must pass."""
    from mcap.writer import Writer

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "back-in-time.mcap"
        with open(path, "wb") as fh:
            w = Writer(fh)
            w.start()
            a = w.register_channel("/a", "json", w.register_schema("A", "jsonschema", b"{}"))
            b = w.register_channel("/b", "json", w.register_schema("B", "jsonschema", b"{}"))
            for channel, t in ((a, 10), (b, 30), (a, 20), (b, 40)):  # /a at 20 after /b at 30
                w.add_message(channel, log_time=t, publish_time=t, data=b"{}")
            w.finish()
        with pytest.raises(mcap_readers.OutOfOrder, match=r"1 messages .* first on '/a', worst 0.0 ms"):
            mcap_readers.read_with_python(path)
        problems = mcap_readers.check([path], None)
        assert len(problems) == 1 and "strict-message-order" in problems[0]


def test_the_writer_keeps_log_times_in_order(tmp_path):
    """Messages handed to the writer out of host-time order (threads, a late frame) get log times
    that never go back; each keeps its own arrival time in its host_time field."""
    from wearbench.acquisition.drivers import Block, BusFrame
    from wearbench.acquisition.session_file import frames

    out = tmp_path / "order.mcap"
    writer = SessionWriter(out)
    writer.start({}, {})
    writer.write_block(Block(ACCELERATION, 0, 0.0, 1000.0, np.zeros(10, np.float32), 100.0))
    writer.write_frame(BusFrame(99.0, 0x20, b"\x01", host_time=99.5, transmitted=True))  # sent before
    writer.write_block(Block(ACCELERATION, 1, 0.01, 1000.0, np.zeros(10, np.float32), 100.2))
    writer.finish()
    mcap_readers.read_with_python(out)  # raises OutOfOrder otherwise
    scan = scan_mcap(out)
    assert [m.log_time for m in scan.messages] == [100_000_000_000, 100_000_000_000, 100_200_000_000]
    (frame,) = frames(scan)
    assert frame.host_time == 99.5 and frame.transmitted and frame.time == 99.0
