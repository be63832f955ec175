"""A tap session over each wire: the serial and CAN emulators fire the tap the recorder commands and
send its latch (serial EVENT with an f64 time; CAN TapLatch with ns), the session file holds it as a
"tap" event, and the tap test recovers the emulator's accel_delay from it."""

from __future__ import annotations

import pytest
from wearbench.acquisition.backends import open_rig
from wearbench.acquisition.recorder import Recorder
from wearbench.acquisition.session import SessionPlan
from wearbench.acquisition.session_file import read_session
from wearbench.acquisition.taps import recorded_taps
from wearbench.validation.measurement.tap_test import tap_test

pytestmark = [pytest.mark.timeout(120), pytest.mark.no_kernels]
DELAY = 0.4e-3


def _config(bench) -> dict:
    """The bench's own emulator (its chain is what the bench states), at rest, late by DELAY."""
    return {**bench.emulator, "signal": "none", "truth": {"accel_delay": f"{DELAY * 1e3!r} ms"}}


def _check(out, taps: int) -> None:
    session = read_session(out)
    assert [t.number for t in recorded_taps(session.events)] == list(range(taps))
    result = tap_test(out)
    assert abs(result.latency - DELAY) < 2e-5


def _record_over_can(bench, tmp_path, backend: str, taps: int, command_delay: float = 0.0):
    """A tap session over the CAN emulator; each tap command reaches the drive ``command_delay`` s late."""
    import threading

    from wearbench.hardware.emulators.can_server import CanEmulator

    channel = f"wearbench-tap-{backend}-{tmp_path.name}"
    out = tmp_path / "taps.mcap"
    with CanEmulator(bench, channel=channel, config=_config(bench)):
        rig = open_rig(bench, backend, {"interface": "virtual", "channel": channel})
        if command_delay:
            send = rig.drive.tap
            rig.drive.tap = lambda *args: threading.Timer(command_delay, send, args).start()
        try:
            result = Recorder(rig, bench, SessionPlan(0.0, taps=taps, settle=0.2), out).run()
        finally:
            rig.close()
    assert result.completed, result.reason
    return out


@pytest.mark.parametrize("backend", ["can", "canopen"])
def test_a_tap_session_over_can(bench, tmp_path, backend):
    _check(_record_over_can(bench, tmp_path, backend, 3), 3)


def test_a_tap_session_over_serial(bench, tmp_path):
    from wearbench.hardware.emulators.serial_server import start_serial_emulator

    proc, port = start_serial_emulator(bench, _config(bench))
    out = tmp_path / "taps.mcap"
    try:
        rig = open_rig(bench, "serial", {"port": port})
        try:
            result = Recorder(rig, bench, SessionPlan(0.0, taps=3, settle=0.2), out).run()
        finally:
            rig.close()
    finally:
        proc.terminate()
        proc.wait(5)
    assert result.completed, result.reason
    _check(out, 3)


def test_a_tap_latched_late_keeps_its_whole_response(bench, tmp_path):
    """A busy host: every tap command reaches the drive 0.2 s after the recorder sent it, so the last
    latch comes 0.2 s later than the plan's interval allows for. The session records on until the
    accelerometer covers the last latch's response, and the tap test gets its whole window."""
    _check(_record_over_can(bench, tmp_path, "can", 2, command_delay=0.2), 2)
