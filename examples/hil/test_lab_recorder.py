"""The lab's recording script (lab_recorder.py) against the emulated test bed, one test per fault:
what the lab's code reports, and that the file keeps every sample the bench sent up to the fault.

The emulator plays a test pattern (``signal="harmonic"``: no model run, so the suite starts in
seconds); ``signal="model"`` plays the physics of the state asked for. Faults start FAULT_AT s of
device time after the stream starts (warm-up and settling take about 0.3 s of it).
"""

from __future__ import annotations

import math

import pytest
from lab_recorder import record_run
from wearbench.testing import FaultPlan, assert_no_sample_lost, assert_valid_mcap, event_time

SPEED = 2 * math.pi  # rad/s: the test bed's 60 rpm
SECONDS = 3.0  # recorded per run (device time)
FAULT_AT = 2.0  # s after the stream starts
SIGNAL = "harmonic"
DRIFT_SECONDS = 6.0  # the clock check fits the whole revolutions of a run


def run(bench, tmp_path, seconds: float = SECONDS, **options):
    """The lab's script on the emulated bench, as it would run on the real one (``options`` added
    to the backend's, e.g. a shorter ``reply_timeout``)."""
    return record_run(bench.bench, bench.backend, {**bench.options, **options}, tmp_path / "run.mcap",
                      speed=SPEED, seconds=seconds)


@pytest.mark.realtime(duration=SECONDS + 1)
def test_a_clean_run_is_usable(serial_bench, tmp_path):
    bench = serial_bench(signal=SIGNAL)
    report = run(bench, tmp_path)
    assert report.completed and report.usable, report
    assert report.seconds >= SECONDS - 0.05  # to the last block
    rate = bench.bench.sensor("accelerometer").sample_rate
    assert report.samples >= SECONDS * rate
    assert_valid_mcap(report.path)
    assert_no_sample_lost(report.path, bench.sent())  # real hardware: no gap in the sequence numbers


@pytest.mark.realtime(duration=FAULT_AT + 3)
def test_lost_link(serial_bench, tmp_path):
    """The pty closes mid-run: the script reports the disconnect, keeps the file, and the file has
    every block the bench sent before the link went down."""
    bench = serial_bench(signal=SIGNAL, faults=FaultPlan(drop_link_at=FAULT_AT))
    report = run(bench, tmp_path, seconds=10)
    assert not report.completed and not report.usable
    assert report.reason.startswith("device disconnected")
    assert 0.3 < report.seconds < FAULT_AT
    assert bench.exit_code() == 3  # the emulator's exit code after an injected link drop
    assert_valid_mcap(report.path)
    from wearbench.acquisition.session_file import read_session

    down = event_time(read_session(report.path), "disconnect")  # the device's last word
    assert down is not None
    assert_no_sample_lost(report.path, bench.sent(), until=down)


@pytest.mark.realtime(duration=SECONDS + 1)
def test_garbage_on_the_line(serial_bench, tmp_path):
    """512 random bytes between two frames: the run completes, the garbage is counted (so the lab
    does not use the run blindly), and no block is lost or altered."""
    bench = serial_bench(signal=SIGNAL, faults=FaultPlan(garbage_at=FAULT_AT, garbage_bytes=512))
    report = run(bench, tmp_path)
    assert report.completed and report.malformed > 0 and not report.usable
    assert report.dropped_blocks == 0
    assert_valid_mcap(report.path)
    assert_no_sample_lost(report.path, bench.sent())


@pytest.mark.realtime(duration=FAULT_AT + 4)
def test_stalled_device(serial_bench, tmp_path):
    """The bench's firmware hangs with the port still open: the script stops with "device stopped
    answering" after the silence timeout, and the file holds every block sent before the hang."""
    bench = serial_bench(signal=SIGNAL, faults=FaultPlan(stall_device_at=FAULT_AT))
    report = run(bench, tmp_path, seconds=10, reply_timeout=0.25)  # a dead device costs 3 tries each
    assert not report.completed and report.reason.startswith("device stopped answering"), report.reason
    assert 0.3 < report.seconds < FAULT_AT
    assert_valid_mcap(report.path)
    assert_no_sample_lost(report.path, bench.sent())  # everything sent (nothing after the hang)


@pytest.mark.realtime(duration=FAULT_AT + 2)
def test_motor_fault(canopen_bench, tmp_path):
    """The motor stalls on the CiA 402 drive (EMCY 0x7121, drive in FAULT): the script stops with
    the drive fault, and the file keeps every block sent up to the fault."""
    bench = canopen_bench(signal=SIGNAL, faults=FaultPlan(motor_fault_at=FAULT_AT))
    report = run(bench, tmp_path, seconds=10)
    assert not report.completed and report.reason == "drive fault: stall"
    assert report.seconds > 0.3  # recorded on until the stream stopped: the data around the fault
    assert_valid_mcap(report.path)
    from wearbench.acquisition.session_file import read_session

    stalled = event_time(read_session(report.path), "stall")
    assert stalled is not None
    assert_no_sample_lost(report.path, bench.sent(), until=stalled)


@pytest.mark.realtime(duration=SECONDS + 1)
def test_lost_index_pulse(serial_bench, tmp_path):
    """The index line breaks: every sample still arrives and the run completes, but the lab's rule
    (an index pulse every revolution) marks the run unusable."""
    bench = serial_bench(signal=SIGNAL, faults=FaultPlan(lose_index_at=FAULT_AT))
    report = run(bench, tmp_path)
    assert report.completed and report.dropped_blocks == 0
    revolutions_after = (SECONDS - (FAULT_AT - 0.3)) * SPEED / (2 * math.pi)
    assert report.index_gap > 1.5 and report.index_gap > 0.8 * revolutions_after
    assert not report.usable
    assert_no_sample_lost(report.path, bench.sent())


@pytest.mark.realtime(duration=2 * (DRIFT_SECONDS + 1))
@pytest.mark.parametrize("ppm", [20, 1000])
def test_clock_drift(serial_bench, tmp_path, ppm):
    """An accelerometer clock running fast: its blocks are still stamped at the nominal rate, so
    the acceleration slides against the encoder's angle; the lab's check reads the drift from the
    signal's once-per-revolution phase and refuses a run beyond its limit (200 ppm)."""
    bench = serial_bench(signal=SIGNAL, faults=FaultPlan(clock_drift=f"{ppm} ppm"))
    report = run(bench, tmp_path, seconds=DRIFT_SECONDS)
    assert report.completed and report.dropped_blocks == 0
    assert report.clock_drift == pytest.approx(ppm * 1e-6, abs=60e-6)
    assert report.usable == (ppm < 200)
    assert_no_sample_lost(report.path, bench.sent())
