"""A recorded session is never lost to the next one: an existing file is refused (or, when forced,
replaced only by a finished session that recorded something), two recorders cannot share a path,
a crashed session's device state does not block the next one, and `--cycles N` records N complete
cycles as the analysis counts them."""

from __future__ import annotations

import errno
import json
import math

import pytest
from wearbench.acquisition.backends import open_rig
from wearbench.acquisition.drivers import DriverError
from wearbench.acquisition.recorder import Recorder
from wearbench.acquisition.session import SessionPlan
from wearbench.acquisition.session_file import read_session
from wearbench.acquisition.session_writer import SessionWriter
from wearbench.cli import main
from wearbench.validation.measurement.cycles import cut_cycles

from .conftest import FAST, HARMONIC

OLD = b"a good session recorded yesterday"


def _record_args(bench, out, tmp_path, *extra):
    config = tmp_path / "emulator.json"
    config.write_text(json.dumps(HARMONIC))
    return ["record", str(bench.path), "--backend", "sim", "--option", "speedup=inf", "--option",
            f"config={config}", "--speed", f"{FAST}", "--cycles", "2", "--out", str(out), *extra]


def test_record_refuses_an_existing_file(bench, tmp_path, capsys):
    out = tmp_path / "s.mcap"
    out.write_bytes(OLD)
    assert main(_record_args(bench, out, tmp_path)) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(out) in err and "--force" in err
    assert out.read_bytes() == OLD


def test_force_keeps_the_old_file_until_the_new_one_is_finished(bench, tmp_path):
    out = tmp_path / "s.mcap"
    out.write_bytes(OLD)
    writer = SessionWriter(out, replace=True)
    assert writer.path == tmp_path / "s.mcap.new"
    writer.start({"session": {"operator": "pytest"}}, {})
    assert out.read_bytes() == OLD  # while recording, the old session is whole
    writer.finish()
    assert writer.path == out and not (tmp_path / "s.mcap.new").exists()
    assert read_session(out).finished
    assert list(tmp_path.iterdir()) == [out]  # no lock or ballast file left behind


def test_force_through_the_cli_replaces_with_a_finished_session(bench, tmp_path):
    out = tmp_path / "s.mcap"
    out.write_bytes(OLD)
    assert main(_record_args(bench, out, tmp_path, "--force")) == 0
    assert read_session(out).metadata["result"]["completed"] == "True"


def test_force_does_not_write_over_a_leftover_of_a_killed_forced_session(bench, tmp_path, capsys):
    # a forced recorder killed mid-session leaves s.mcap.new: maybe the only copy of that recording
    out, new = tmp_path / "s.mcap", tmp_path / "s.mcap.new"
    out.write_bytes(OLD)
    new.write_bytes(b"half a session from a killed forced run")
    with pytest.raises(FileExistsError, match="left over") as info:
        SessionWriter(out, replace=True)
    assert str(new) in str(info.value)
    assert main(_record_args(bench, out, tmp_path, "--force")) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(new) in err and "left over" in err and "recover" in err
    assert out.read_bytes() == OLD and new.read_bytes() == b"half a session from a killed forced run"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["emulator.json", "s.mcap", "s.mcap.new"]  # no lock left
    new.unlink()  # moved away: the forced session goes ahead
    assert main(_record_args(bench, out, tmp_path, "--force")) == 0
    assert read_session(out).finished


def test_two_writers_on_one_path(tmp_path):
    out = tmp_path / "s.mcap"
    first = SessionWriter(out)
    for replace in (False, True):
        with pytest.raises(OSError) as info:
            SessionWriter(out, replace=replace)
        assert info.value.errno == errno.EBUSY and str(out) in str(info.value)
    first.start({}, {})
    first.finish()
    with pytest.raises(FileExistsError, match="already exists"):
        SessionWriter(out)


def test_a_failed_start_never_writes_over_an_existing_file(bench, tmp_path):
    out = tmp_path / "s.mcap"
    out.write_bytes(OLD)
    rig = open_rig(bench, "sim", {"speedup": math.inf, "config": HARMONIC})

    def busy(*args):
        raise DriverError("CONFIGURE_ACCEL: BUSY")

    for source in rig.sources:
        source.configure = busy
    try:
        result = Recorder(rig, bench, SessionPlan(speed=FAST, cycles=2), out,
                          writer=SessionWriter(out, replace=True)).run()
    finally:
        rig.close()
    assert not result.completed and "BUSY" in result.reason
    assert out.read_bytes() == OLD
    assert result.path == tmp_path / "s.mcap.new"  # the failed attempt says why, beside it
    assert "BUSY" in read_session(result.path).metadata["result"]["reason"]


@pytest.mark.parametrize("cycles", [5, 2.5])
def test_cycles_are_complete_cycles(bench, tmp_path, cycles):
    out = tmp_path / "s.mcap"
    rig = open_rig(bench, "sim", {"speedup": math.inf, "config": HARMONIC})
    try:
        result = Recorder(rig, bench, SessionPlan(speed=FAST, cycles=cycles), out).run()
    finally:
        rig.close()
    assert result.completed
    assert len(cut_cycles(read_session(out).encoder)) == math.ceil(cycles)


def test_serial_device_left_streaming_by_a_crash_is_reset_on_connect(bench, tmp_path):
    """A recorder killed mid-session leaves the device streaming; the next one still starts."""
    from wearbench.hardware.emulators.serial_server import start_serial_emulator

    proc, port = start_serial_emulator(bench, HARMONIC)
    try:
        crashed = open_rig(bench, "serial", {"port": port})
        accel = bench.sensor("accelerometer")
        crashed.sources[0].configure(accel.range, accel.sample_rate)
        crashed.sources[0].start()
        crashed.close()  # no stop: as if the process died
        out = tmp_path / "s.mcap"
        rig = open_rig(bench, "serial", {"port": port})
        try:
            result = Recorder(rig, bench, SessionPlan(speed=FAST, cycles=2), out).run()
        finally:
            rig.close()
    finally:
        proc.terminate()
        proc.wait(timeout=10)
    assert result.completed, result.reason


def test_wear_files_are_checked_and_travel_in_the_session(bench, tmp_path, capsys):
    """`--wear A=missing.npz` is refused before the rig starts; a named surface file is embedded, so
    the session can be scored after the file moved."""
    import numpy as np
    from wearbench.model.surfaces import JointSurfaces
    from wearbench.validation.comparison.theory import resolve_surfaces

    out = tmp_path / "s.mcap"
    assert main([*_record_args(bench, out, tmp_path), "--wear", "A=missing.npz"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "missing.npz" in err and "does not exist" in err and not out.exists()
    worn = JointSurfaces(np.linspace(0, 1e-5, 100), np.zeros(100), 1e5, "stage 1")
    path = worn.save(tmp_path / "stage1.npz")
    assert main([*_record_args(bench, out, tmp_path), "--wear", f"A={path}"]) == 0
    path.rename(tmp_path / "moved.npz")
    session = read_session(out)
    with pytest.raises(ValueError, match="neither"):
        resolve_surfaces(session.wear_state)  # the file is gone and no copy given
    again = resolve_surfaces(session.wear_state, embedded=session.surface_files)["A"]
    np.testing.assert_array_equal(again.bearing, worn.bearing)
