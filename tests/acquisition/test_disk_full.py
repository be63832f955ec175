"""A full disk, for real: recording into a 3 MiB tmpfs ends with a finished file whose stop reason
is ``disk full`` and which holds every block the recorder received; too little free space is
refused before anything starts. Needs root to mount the tmpfs (skips with the reason otherwise)."""

from __future__ import annotations

import errno
import math
import os
import shutil
import subprocess
import sys
import threading

import numpy as np
import pytest
from wearbench.acquisition.backends import open_rig
from wearbench.acquisition.drivers import ACCELERATION, ENCODER
from wearbench.acquisition.recorder import Recorder
from wearbench.acquisition.session import SessionPlan
from wearbench.acquisition.session_file import read_session
from wearbench.acquisition.session_writer import MIN_FREE_BYTES, NotEnoughSpace, SessionWriter
from wearbench.cli.progress import COMPILING

from .conftest import FAST, HARMONIC, assert_same_blocks, recorded_blocks, sent_from_device


@pytest.fixture
def small_fs(tmp_path):
    """A 3 MiB tmpfs mounted for the test."""
    where = tmp_path / "small"
    where.mkdir()
    if shutil.which("mount") is None:
        pytest.skip("no mount command")
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=3m", "tmpfs", str(where)],
                       capture_output=True, text=True, check=False)
    if r.returncode:
        pytest.skip(f"cannot mount a tmpfs here ({r.stderr.strip() or r.returncode}): needs root")
    try:
        yield where
    finally:
        subprocess.run(["umount", "-l", str(where)], check=False)


def _fill(where, leave: int) -> None:
    """Fill the filesystem at ``where`` until ``leave`` bytes are free."""
    free = shutil.disk_usage(where).free
    with open(where / "filler", "wb") as fh:
        fh.write(bytes(max(0, free - leave)))


def test_disk_full_on_a_real_filesystem(bench, small_fs, tmp_path):
    _fill(small_fs, 1_400_000)  # a 3 MiB filesystem with 1.4 MB left: full after ~1 min of 10 kHz
    rig = open_rig(bench, "sim", {"speedup": math.inf, "config": HARMONIC})
    sent = sent_from_device(rig.drive.device)
    out = small_fs / "full.mcap"
    try:
        result = Recorder(rig, bench, SessionPlan(speed=FAST, duration=600.0), out).run()
    finally:
        rig.close()
    kept = tmp_path / "full.mcap"  # outlives the mount, for the suite-wide reader check
    shutil.copyfile(out, kept)
    assert result.reason.startswith("disk full: [Errno 28]"), result.reason
    assert 10 < result.duration < 120
    s = read_session(kept)
    assert s.finished and s.metadata["result"]["reason"] == result.reason
    assert s.metadata["result"]["lost_items"] == "0"
    assert (s.events.kind == "error").any() and s.events.message.str.contains("reserved inside the file").any()
    # nothing received was lost: every block the writer was handed is in the file, in sequence
    rec = recorded_blocks(kept)
    for stream in (ACCELERATION, ENCODER):
        assert len(rec[stream]) == result.blocks[stream]
    assert_same_blocks(kept, sent, min_blocks=100)
    assert s.quality[ACCELERATION]["dropped"] == 0
    assert np.isclose(len(s.acceleration), result.samples[ACCELERATION])
    assert not (small_fs / "full.mcap.ballast").exists()


class Competitor(threading.Thread):
    """Another program that takes every byte the moment it is free (a log, a second recorder)."""

    def __init__(self, where, after):
        super().__init__(daemon=True)
        self.after = after  # (path, size): start once the session file is that big
        self.where, self.halt, self.taken, self.refused = where, threading.Event(), 0, 0

    def run(self) -> None:
        path, size = self.after
        while not self.halt.is_set() and not (path.exists() and path.stat().st_size > size):
            self.halt.wait(0.01)
        fd = os.open(self.where / "greedy", os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
        try:
            while not self.halt.is_set():
                try:
                    self.taken += os.write(fd, bytes(4096))
                except OSError as exc:
                    assert exc.errno == errno.ENOSPC
                    self.refused += 1
                    self.halt.wait(0.0005)
        finally:
            os.close(fd)


def test_disk_full_while_another_program_takes_every_freed_byte(bench, small_fs, tmp_path):
    """Issue 25, item 4: with a competing writer the file used to end without summary or stop reason
    (exit 2) and 0.56 s of received blocks were lost after recover. The session file's own reserved
    room holds its end: finished, reason recorded, every block the recorder received in it."""
    _fill(small_fs, 1_400_000)
    rig = open_rig(bench, "sim", {"speedup": math.inf, "config": HARMONIC})
    sent = sent_from_device(rig.drive.device)
    out = small_fs / "full.mcap"
    greedy = Competitor(small_fs, after=(out, 300_000))
    try:
        recorder = Recorder(rig, bench, SessionPlan(speed=FAST, duration=600.0), out)
        greedy.start()  # once 300 kB are recorded, nothing freed stays free
        result = recorder.run()
    finally:
        greedy.halt.set()
        greedy.join(timeout=10)
        rig.close()
    assert greedy.taken > 0 and greedy.refused > 100  # it had the disk full the whole time
    kept = tmp_path / "full.mcap"
    shutil.copyfile(out, kept)
    assert result.reason.startswith("disk full: [Errno 28]"), result.reason
    s = read_session(kept)
    assert s.finished and s.metadata["result"]["reason"] == result.reason
    assert s.metadata["result"]["lost_items"] == "0"
    rec = recorded_blocks(kept)
    for stream in (ACCELERATION, ENCODER):
        assert len(rec[stream]) == result.blocks[stream] > 100
    assert_same_blocks(kept, sent, min_blocks=100)
    assert s.quality[ACCELERATION]["dropped"] == 0


def test_too_little_space_is_refused(bench, small_fs, tmp_path):
    _fill(small_fs, MIN_FREE_BYTES // 2)
    with pytest.raises(NotEnoughSpace, match="MiB free; a session needs at least 1 MiB"):
        SessionWriter(small_fs / "s.mcap")
    assert not (small_fs / "s.mcap").exists()
    r = subprocess.run([sys.executable, "-m", "wearbench.cli", "record", str(bench.path), "--backend", "sim",
                        "--option", "speedup=inf", "--cycles", "1", "--out", str(small_fs / "s.mcap")],
                       capture_output=True, text=True, timeout=120, check=False)
    assert r.returncode == 2
    said = [x for x in r.stderr.splitlines() if x != COMPILING]  # a cold kernel cache says so first
    assert said[0].startswith("wearbench record: error: [Errno 28] 0.") and "needs at least 1 MiB" in said[0], r.stderr
    assert not (small_fs / "s.mcap").exists()
