"""Issue 25, item 11: every subcommand, given a foreign MCAP (another tool's protobuf on a session
topic), a truncated session, an empty file or a wrong .npz where it expects a file, answers with one
line naming the file (exit 2), never a traceback; a truncated session is still read where that is
the point (inspect, recover). `inspect | head` ends quietly."""

from __future__ import annotations

import json
import struct
import subprocess
import sys

import numpy as np
import pytest
from google.protobuf import descriptor_pb2
from mcap.writer import Writer
from wearbench.cli import main

from .acquisition.conftest import FAST, HARMONIC


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    where = tmp_path_factory.mktemp("inputs")
    fds = descriptor_pb2.FileDescriptorSet()
    f = fds.file.add(name="imu.proto", package="other", syntax="proto3")
    m = f.message_type.add(name="Imu")
    m.field.add(name="x", number=1, type=descriptor_pb2.FieldDescriptorProto.TYPE_DOUBLE)
    with open(where / "foreign.mcap", "wb") as fh:
        w = Writer(fh)
        w.start(profile="", library="another tool")
        cid = w.register_channel("/acceleration", "protobuf", w.register_schema("other.Imu", "protobuf",
                                                                                fds.SerializeToString()))
        for i in range(50):
            w.add_message(cid, i * 1_000_000, b"\x09" + struct.pack("<d", float(i)), i * 1_000_000)
        w.finish()
    config = where / "emulator.json"
    config.write_text(json.dumps(HARMONIC))
    session = where / "s.mcap"
    assert main(["record", "ninebar-testbed", "--backend", "sim", "--option", "speedup=inf", "--option",
                 f"config={config}", "--speed", f"{FAST}", "--cycles", "3", "--out", str(session)]) == 0
    data = session.read_bytes()
    (where / "cut.mcap").write_bytes(data[: len(data) // 2])
    (where / "empty.mcap").write_bytes(b"")
    np.savez(where / "wrong.npz", x=np.arange(3))
    return where


COMMANDS = [  # {f}: the bad input; {s}: a good session; {d}: a folder for outputs
    "inspect {f}", "recover {f} --out {d}/r.mcap", "compare {f} --out {d}/c", "identify {f}",
    "identify {s} --ensembles {f}", "compare {s} --theory {f} --out {d}/c",
    "compare {s} --candidates {f} --out {d}/c", "simulate slider-crank --surfaces S={f} --revolutions 0.1",
    "bench show {f}", "bench check {f}", "bench copy {f} {d}/b.toml", "simulate {f}", "wear {f} --out {d}/w",
    "sweep {f} --vary speed=1 --out {d}/sw", "study {f} --quick --out {d}/st", "ensemble {f}",
    "ensemble ninebar-testbed --candidates {f} --out {d}/e.npz", "record {f} --cycles 1 --out {d}/x.mcap",
    "record ninebar-testbed --backend sim --cycles 1 --wear A={f} --out {d}/y.mcap", "emulate {f} --serial",
    "emulate ninebar-testbed --serial --config {f}", "estimate {f}", "estimate {s} --estimator {f}",
    "track {f} --cycles-run 0", "track {s} --cycles-run 0 --estimator {f}", "calibrate {f} --state x",
    "calibrate {s} --state x --ensembles {f}", "estimator {f}", "taptest ninebar-testbed --session {f}",
    "taptest {f} --session {s}",
]
READABLE = {("inspect {f}", "cut.mcap")}  # what it is for: an unfinished file says what it holds


@pytest.mark.parametrize("bad", ["foreign.mcap", "cut.mcap", "empty.mcap", "wrong.npz"])
@pytest.mark.parametrize("command", COMMANDS)
def test_every_command_answers_a_broken_input_in_one_line(command, bad, files, tmp_path, capsys):
    argv = command.format(f=files / bad, s=files / "s.mcap", d=tmp_path).split()
    capsys.readouterr()
    with pytest.raises(SystemExit) as info:  # argparse's own exit, or ours
        raise SystemExit(main(argv))
    err = [x for x in capsys.readouterr().err.splitlines() if not x.startswith("compiling")]
    if (command, bad) in READABLE:
        assert info.value.code == 0, err
        return
    assert info.value.code == 2, (argv, err)
    said = [x for x in err if x.startswith(("wearbench", "usage", " ")) or "Error" in x]  # not progress lines
    assert len(said) == 1 or said[-1].startswith("wearbench") and "usage" in said[0], err
    assert "Traceback" not in "\n".join(err) and bad in said[-1], err


def test_inspect_into_a_closed_pipe_ends_quietly(files):
    proc = subprocess.Popen([sys.executable, "-m", "wearbench.cli", "inspect", str(files / "s.mcap")],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()  # `| head` that has read all it wanted
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0 and err == b"", err
