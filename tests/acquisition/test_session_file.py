"""The session file on its own: message encoding round trips, a file cut at any byte is read up to
its last complete chunk (and recovered to exactly that), `wearbench record` and `inspect` on the
command line, and the durable file's handling of a failed write."""

from __future__ import annotations

import errno
import io
import json
import math
import subprocess
import sys

import numpy as np
import pytest
from mcap.reader import make_reader
from wearbench.acquisition.drivers import ACCELERATION, ENCODER, Block
from wearbench.acquisition.layout import decode_block, encode_block
from wearbench.acquisition.recover import recover
from wearbench.acquisition.session_file import read_session, scan_mcap
from wearbench.acquisition.session_writer import DurableFile
from wearbench.acquisition.summary import format_summary, summarize

from .conftest import FAST, HARMONIC, recorded_blocks


def test_block_encoding_is_exact():
    rng = np.random.default_rng(1)
    acc = Block(ACCELERATION, 7, 12.3456789012, 20000.0, rng.normal(0, 50, 400).astype(np.float32), 1.7e9)
    acc.samples[:3] = [np.float32(np.nan), np.float32(-0.0), np.finfo(np.float32).tiny]
    back = decode_block(ACCELERATION, encode_block(acc))
    assert back.samples.tobytes() == acc.samples.tobytes()  # bit for bit, NaN and -0 included
    assert (back.sequence, back.device_time, back.sample_rate, back.host_time) == (7, 12.3456789012, 20000.0, 1.7e9)
    enc = Block(ENCODER, 2**33, 1.0, 1000.0, np.array([-2**31, 0, 2**31 - 1], dtype=np.int32), 0.0,
                np.array([False, True, False]))
    back = decode_block(ENCODER, encode_block(enc))
    assert back.sequence == 2**33
    np.testing.assert_array_equal(back.samples, enc.samples)
    np.testing.assert_array_equal(back.index, enc.index)


@pytest.fixture(scope="module")
def session_file(tmp_path_factory):
    """A finished 20-cycle sim session recorded through the command line, with small chunks."""
    tmp = tmp_path_factory.mktemp("cli")
    config = tmp / "emulator.json"
    config.write_text(json.dumps(HARMONIC))
    out = tmp / "cli.mcap"
    from wearbench.model.surfaces import JointSurfaces

    JointSurfaces(np.linspace(0, 2e-6, 100), np.zeros(100), 1e5, "worn").save(tmp / "worn.npz")
    r = subprocess.run([sys.executable, "-m", "wearbench.cli", "record", "ninebar-testbed", "--backend", "sim",
                        "--option", "speedup=inf", "--option", f"config={config}", "--speed", f"{FAST}rad/s", "--cycles", "20",
                        "--out", str(out), "--clearance", "A=0.25mm", "--wear", "B=worn.npz"],
                       capture_output=True, text=True, timeout=120, check=False, cwd=tmp)
    assert r.returncode == 0, r.stderr
    assert "completed" in r.stdout and "dropped 0 samples" in r.stdout
    return out


def test_cli_record_and_inspect(session_file):
    s = read_session(session_file)
    assert s.finished and s.clearances == pytest.approx({"A": 0.25e-3, "B": 0.3e-3})
    assert s.wear_state == {"A": "new", "B": "worn.npz"}
    assert set(s.surface_files) == {"B"}  # the worn surface travels in the session
    assert s.metadata["session"]["bench_sha256"] == s.bench.sha256
    with open(session_file, "rb") as fh:  # a standard MCAP reader sees the channels and schemas
        summary = make_reader(fh).get_summary()
    topics = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
    assert topics == {"/acceleration": "wearbench.AccelerationBlock", "/encoder": "wearbench.EncoderBlock",
                      "/motor/state": "wearbench.MotorState", "/motor/command": "wearbench.MotorCommand",
                      "/events": "foxglove.Log"}  # /can/frames only on the CAN backends
    r = subprocess.run([sys.executable, "-m", "wearbench.cli", "inspect", str(session_file)],
                       capture_output=True, text=True, timeout=60, check=False)
    assert r.returncode == 0, r.stderr
    acc = next(line for line in r.stdout.splitlines() if line.strip().startswith("/acceleration"))
    fields = acc.split()
    assert fields[4] == "10000.0Hz" and fields[5:8] == ["0", "0", "0"]  # rate; no drops, repeats, gaps
    assert "bench_sha256" in r.stdout and "[calibration]" in r.stdout and "bench.toml" in r.stdout


@pytest.fixture(scope="module")
def chunked_file(tmp_path_factory, bench):
    """A sim session written with 16 KiB chunks (many chunks to cut between)."""
    from wearbench.acquisition.backends import open_rig
    from wearbench.acquisition.recorder import Recorder
    from wearbench.acquisition.session import SessionPlan
    from wearbench.acquisition.session_writer import SessionWriter

    out = tmp_path_factory.mktemp("chunked") / "chunked.mcap"
    rig = open_rig(bench, "sim", {"speedup": math.inf, "config": HARMONIC})
    try:
        Recorder(rig, bench, SessionPlan(speed=FAST, cycles=5), out,
                 writer=SessionWriter(out, chunk_size=16 << 10)).run()
    finally:
        rig.close()
    return out


def _messages_per_chunk(path) -> list[int]:
    """Messages in each chunk, counted with mcap's own stream reader."""
    from mcap.records import Chunk, Message
    from mcap.stream_reader import StreamReader, breakup_chunk

    with open(path, "rb") as fh:
        return [sum(isinstance(r, Message) for r in breakup_chunk(c))
                for c in StreamReader(fh, emit_chunks=True).records if isinstance(c, Chunk)]


def test_cut_file_reads_and_recovers_every_complete_chunk(chunked_file, tmp_path):
    data = chunked_file.read_bytes()
    with open(chunked_file, "rb") as fh:
        index = make_reader(fh).get_summary().chunk_indexes
    per_chunk = _messages_per_chunk(chunked_file)
    assert len(index) == len(per_chunk) >= 3
    full = recorded_blocks(chunked_file)[ACCELERATION]
    ends = [c.chunk_start_offset + c.chunk_length for c in index]
    cuts = sorted(set(ends[:-1]) | {e - 7 for e in ends} | {9, 100, len(data) - 5})
    for cut in cuts:
        broken = tmp_path / "broken.mcap"
        broken.write_bytes(data[:cut])
        complete = sum(e <= cut for e in ends)
        scan = scan_mcap(broken)  # never raises
        assert not scan.finished and scan.chunks == complete
        assert len(scan.messages) == sum(per_chunk[:complete])
        if not complete:
            continue
        fixed = tmp_path / "fixed.mcap"
        r = recover(broken, fixed, force=True)  # the previous cut's
        assert r.messages == sum(per_chunk[:complete])
        got = recorded_blocks(fixed)[ACCELERATION]
        for seq, block in got.items():
            np.testing.assert_array_equal(block.samples, full[seq].samples)
        s = read_session(fixed)
        assert s.finished and s.metadata["recovery"]["chunks"] == str(complete)


def test_inspect_unfinished(chunked_file, tmp_path):
    broken = tmp_path / "half.mcap"
    data = chunked_file.read_bytes()
    with open(chunked_file, "rb") as fh:
        index = make_reader(fh).get_summary().chunk_indexes
    middle = index[len(index) // 2]  # cut inside a chunk in the middle of the data
    broken.write_bytes(data[: middle.chunk_start_offset + middle.chunk_length // 2])
    text = format_summary(summarize(broken))
    assert "NOT finished" in text and "/acceleration" in text


def test_read_session_rejects_other_files(tmp_path):
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not an mcap file at all")
    with pytest.raises(ValueError, match="not an MCAP file"):
        read_session(junk)


class _Flaky(io.BytesIO):
    def __init__(self):
        super().__init__()
        self.fail = 0

    def write(self, data):
        if self.fail:
            self.fail -= 1
            super().write(bytes(data)[:3])  # a torn write
            raise OSError(errno.ENOSPC, "No space left on device")
        return super().write(data)


def test_durable_file_keeps_failed_writes():
    raw = _Flaky()
    f = DurableFile(raw)
    f.write(b"abc")
    raw.fail = 2
    f.write(b"defghij")  # fails: cut back, kept in memory
    assert raw.getvalue() == b"abc" and f.tell() == 10 and isinstance(f.error, OSError)
    f.error = None
    f.write(b"kl")  # the backlog fails again, still nothing torn
    assert raw.getvalue() == b"abc" and f.backlog == 9
    f.write(b"m")  # room again: everything lands in order
    assert raw.getvalue() == b"abcdefghijklm" and f.backlog == 0 and f.tell() == 13
    assert math.isclose(f.tell(), len(raw.getvalue()))
