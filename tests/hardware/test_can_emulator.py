"""The CAN emulator on the python-can virtual bus: raw DBC frames and the CANopen CiA 402 drive."""

from __future__ import annotations

import itertools
import time

import can
import canopen
import pytest
from wearbench.hardware.emulators.can_server import CAN_ERR_BUSOFF, CanEmulator
from wearbench.hardware.protocol import can_frames as cf
from wearbench.hardware.protocol.blocks import AccelBlock, EncoderBlock

pytestmark = [pytest.mark.timeout(120), pytest.mark.no_kernels]
_channels = itertools.count()


@pytest.fixture
def channel():
    return f"wearbench-test-{next(_channels)}"


def collect(bus: can.BusABC, seconds: float) -> list[can.Message]:
    out, end = [], time.monotonic() + seconds
    while time.monotonic() < end:
        msg = bus.recv(0.05)
        if msg is not None:
            out.append(msg)
    return out


def named(msgs, name):
    return [v for n, v in (cf.decode_frame(x) or (None, None) for x in msgs if not x.is_error_frame) if n == name]


def command(bus, cmd, counter, speed=0.0):
    bus.send(cf.encode_frame("MotorCommand", {"Command": cmd, "Counter": counter, "TargetSpeed": speed,
                                              "Acceleration": 0}))


def start(bus, speed=6.2832):
    command(bus, 1, 1)
    command(bus, 3, 2, speed)
    bus.send(cf.encode_frame("StreamControl", {"Command": 1, "Mask": 3, "Range": 0, "SampleRate": 0}))


def test_raw_frames_deliver_exactly_what_was_sent(testbed, channel):
    with CanEmulator(testbed, channel, {"signal": "harmonic", "accelerometer": {"noise": "1 m/s^2"}}) as emu:
        bus = can.Bus(interface="virtual", channel=channel, fd=True)
        start(bus)
        msgs = collect(bus, 1.0)
        bus.send(cf.encode_frame("StreamControl", {"Command": 0, "Mask": 3, "Range": 0, "SampleRate": 0}))
        msgs += collect(bus, 0.2)
        bus.shutdown()
        status = named(msgs, "StreamStatus")[-1]
        lsb = cf.accel_lsb(status["Range"])
        got = [cf.decode_accel_frame(v, lsb, status["SampleRate"]) for v in named(msgs, "AccelBlock")]
        got_enc = [cf.decode_encoder_frame(v, testbed.sensor("encoder").sample_rate) for v in named(msgs, "EncoderBlock")]
        assert len(got) > 300 and got == [b for b in emu.sent if isinstance(b, AccelBlock)]
        assert got_enc == [b for b in emu.sent if isinstance(b, EncoderBlock)]
        assert len({b.sequence for b in got}) == len(got) and got[-1].sequence == len(got) - 1
        acks = named(msgs, "MotorStatus")
        assert acks[-1]["Speed"] == pytest.approx(6.2832, rel=1e-3) and acks[-1]["Enabled"] == 1
        assert {a["AckCounter"] for a in acks} >= {2}


def test_refused_command_reports_its_error(testbed, channel):
    with CanEmulator(testbed, channel, {"signal": "none"}):
        bus = can.Bus(interface="virtual", channel=channel, fd=True)
        command(bus, 3, 7, 1.0)  # not enabled
        acks = [v for v in named(collect(bus, 0.3), "MotorStatus") if v["AckCounter"] == 7]
        bus.shutdown()
        assert acks and acks[0]["AckError"] == 4


def test_bus_off_corruption_and_late_replies(testbed, channel):
    cfg = {"signal": "none", "faults": {"bus_off_at": "0.3 s", "bus_off_duration": "0.3 s", "corrupt_rate": 0.05,
                                         "reply_delay": "0.3 s"}}
    with CanEmulator(testbed, channel, cfg):
        bus = can.Bus(interface="virtual", channel=channel, fd=True)
        t0 = time.monotonic()
        command(bus, 1, 3)
        first = None
        while first is None and time.monotonic() - t0 < 3:
            msg = bus.recv(0.05)
            if msg is not None and not msg.is_error_frame and cf.decode_frame(msg)[0] == "MotorStatus" \
                    and cf.decode_frame(msg)[1]["AckCounter"] == 3:
                first = time.monotonic() - t0
        assert first is not None and first >= 0.3
        start(bus)
        msgs = collect(bus, 1.5)
        bus.shutdown()
    errors = [x for x in msgs if x.is_error_frame]
    assert any(x.arbitration_id == CAN_ERR_BUSOFF for x in errors) and len(errors) > 2
    events = named(msgs, "Event")
    assert any(e["Code"] == 4 and e["Detail"] == 300 for e in events)
    seqs = [v["Sequence"] for v in named(msgs, "AccelBlock")]
    gaps = [b - a for a, b in itertools.pairwise(seqs) if b - a > 1]
    assert max(gaps) >= 0.25 * 10000 / 24  # ~0.3 s of blocks lost while off the bus


def test_bus_off_loses_the_blocks_sampled_while_off_however_late_the_emulator_runs(testbed, channel):
    """A starved emulator (one pass every 0.25 s, as on a loaded host) loses exactly the blocks
    sampled in the 0.3 s off the bus, not those it got to during it: the gap is 0.3-0.6 s of the
    stream, to a block."""
    cfg = {"signal": "none", "faults": {"bus_off_at": "0.3 s", "bus_off_duration": "0.3 s"}}
    with CanEmulator(testbed, channel, cfg, period=0.25) as emu:
        bus = can.Bus(interface="virtual", channel=channel, fd=True)
        start(bus)
        msgs = collect(bus, 1.5)
        bus.shutdown()
    seqs = [v["Sequence"] for v in named(msgs, "AccelBlock")]
    block = cf.ACCEL_PER_FRAME / emu.device.sample_rate  # s per block
    gaps = [(a, b) for a, b in itertools.pairwise(seqs) if b - a > 1]
    assert len(gaps) == 1, gaps
    first_lost, next_kept = (gaps[0][0] + 1 - seqs[0]) * block, (gaps[0][1] - seqs[0]) * block
    assert abs(first_lost - 0.3) <= block and abs(next_kept - 0.6) <= block, (first_lost, next_kept)


def test_disconnect_goes_silent(testbed, channel):
    with CanEmulator(testbed, channel, {"signal": "none", "faults": {"disconnect_after": "0.3 s"}}):
        bus = can.Bus(interface="virtual", channel=channel, fd=True)
        start(bus)
        collect(bus, 0.6)
        assert collect(bus, 0.4) == []
        bus.shutdown()


def test_canopen_drive_state_machine_and_pdos(testbed, channel):
    with CanEmulator(testbed, channel, {"signal": "none", "faults": {"stall_at": "0.8 s"}}):
        net = canopen.Network()
        net.connect(interface="virtual", channel=channel)
        try:
            node = canopen.RemoteNode(5, str(cf.EDS_PATH))
            net.add_node(node)
            assert node.sdo["Statusword"].raw & 0x4F == 0x40  # switch on disabled
            assert node.sdo["Modes of operation"].raw == 3
            with pytest.raises(canopen.SdoAbortedError):
                node.sdo["Modes of operation"].raw = 1
            node.nmt.state = "OPERATIONAL"
            expected = {0x06: 0x21, 0x07: 0x23, 0x0F: 0x27}
            for cw, sw in expected.items():
                node.sdo["Controlword"].raw = cw
                assert node.sdo["Statusword"].raw & 0x6F == sw
            node.sdo["Target velocity"].raw = 4000  # mrad/s
            time.sleep(0.3)
            assert node.sdo["Velocity actual value"].raw == 4000
            node.tpdo.read()
            assert node.tpdo[1].wait_for_reception(1.0)
            assert node.tpdo[1]["Velocity actual value"].raw == 4000
            # RPDO: new target through the process data
            node.rpdo.read()
            node.rpdo[1]["Controlword"].raw = 0x0F
            node.rpdo[1]["Target velocity"].raw = -2000
            node.rpdo[1].transmit()
            time.sleep(0.2)
            assert node.sdo["Velocity actual value"].raw == -2000
            p0 = node.sdo["Position actual value"].raw
            time.sleep(0.2)
            assert node.sdo["Position actual value"].raw < p0
            # stall: fault state, error code, EMCY
            net.bus.send(cf.encode_frame("StreamControl", {"Command": 1, "Mask": 3, "Range": 0, "SampleRate": 0}))
            err = node.emcy.wait(0x7121, timeout=2.0)
            assert err is not None
            assert node.sdo["Statusword"].raw & 0x4F == 0x08 and node.sdo["Error code"].raw == 0x7121
            node.sdo["Controlword"].raw = 0x80  # fault reset
            assert node.sdo["Statusword"].raw & 0x4F == 0x40 and node.sdo["Error code"].raw == 0
        finally:
            net.disconnect()


def test_only_the_virtual_bus(testbed):
    with pytest.raises(ValueError, match="virtual"):
        CanEmulator(testbed, "x", {"signal": "none"}, interface="udp_multicast")
