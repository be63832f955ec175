"""Serial framing and messages, the DBC, and the CiA 402 EDS."""

from __future__ import annotations

import canopen
import cantools
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from wearbench.hardware.protocol import can_frames as cf
from wearbench.hardware.protocol import messages as m
from wearbench.hardware.protocol.blocks import AccelBlock, EncoderBlock
from wearbench.hardware.protocol.frames import (
    MAX_PAYLOAD,
    SYNC,
    Frame,
    FrameParser,
    crc8,
    crc16,
    encode_frame,
)

pytestmark = pytest.mark.no_kernels

ALL_MESSAGES = [
    m.GetInfo(), m.Enable(), m.Disable(), m.SetSpeed(6.25, 100.0), m.SetProfile((0.0, 1.5), (2.0, -3.0), 50.0),
    m.Stop(), m.ConfigureAccel(490.0, 20000.0), m.StartStream(3), m.StopStream(), m.GetStatus(), m.ClearFault(),
    m.Ack(4, 65535, m.ErrorCode.NOT_ENABLED), m.Status(1.5, -2.25, 6.25, -12, 7, 5, 1, 490.0, 20000.0),
    m.Info(1, 4000, 200, 10, "bench"), m.Event(2.5, m.FaultCode.STALL, "stall"),
    m.AccelData(9, 0.25, 20000.0, 0.015, m.SampleFormat.INT16, np.array([-32768, 0, 32767], np.int16)),
    m.AccelData(10, 0.5, 20000.0, 0.015, m.SampleFormat.INT32, np.array([-70000, 1, 70000], np.int32)),
    m.AccelData(11, 0.75, 20000.0, 1.0, m.SampleFormat.FLOAT32, np.array([1.5, -2.5], np.float32)),
    m.EncoderData(3, 0.01, 1000.0, np.array([1, 2, 3, 2**31 - 1], np.int32), np.array([0, 1, 0, 1], bool)),
]


def test_crc_check_values():
    # published check values of CRC-8 (poly 0x07) and CRC-16/CCITT-FALSE
    assert crc8(b"123456789") == 0xF4
    assert crc16(b"123456789") == 0x29B1


def test_frame_layout_matches_spec():
    data = encode_frame(0x04, 0x1234, b"\x01\x02")
    assert data[:2] == SYNC
    assert data[2:4] == b"\x02\x00" and data[4] == 0x04 and data[5:7] == b"\x34\x12"
    assert data[7] == crc8(data[2:7])
    assert int.from_bytes(data[-2:], "little") == crc16(data[2:-2])
    with pytest.raises(ValueError):
        encode_frame(1, 0, bytes(MAX_PAYLOAD + 1))


def test_every_message_round_trips():
    stream = b"".join(msg.frame(i) for i, msg in enumerate(ALL_MESSAGES))
    parser = FrameParser()
    frames = parser.feed(stream)
    assert [f.sequence for f in frames] == list(range(len(ALL_MESSAGES)))
    assert [m.decode(f) for f in frames] == ALL_MESSAGES
    assert parser.stats.crc_errors == parser.stats.bytes_skipped == 0


def test_samples_convert_identically_on_both_sides():
    counts = np.array([-32768, -1, 0, 1, 12345, 32767])
    msg = m.AccelData(0, 0.0, 1e4, 490.0 / 32768, m.SampleFormat.INT16, counts)
    got = m.decode(Frame(msg.TYPE, 0, msg.pack())).samples
    assert got.dtype == np.float32
    np.testing.assert_array_equal(got, m.counts_to_m_s2(counts, 490.0 / 32768))
    np.testing.assert_allclose(got, counts * 490.0 / 32768, rtol=1e-6)


@pytest.mark.parametrize("msg", [m.SetSpeed(1.0), m.Status(0, 0, 0, 0, 0, 0, 0, 0, 0), m.EncoderData(
    0, 0.0, 1.0, np.arange(9, dtype=np.int32), np.zeros(9, bool))])
def test_truncated_payload_is_a_protocol_error(msg):
    payload = msg.pack()
    with pytest.raises(m.ProtocolError, match=msg.TYPE.name):
        m.decode(Frame(msg.TYPE, 0, payload[:-1]))


def test_unknown_type_is_a_protocol_error():
    with pytest.raises(m.ProtocolError, match="0x55"):
        m.decode(Frame(0x55, 0, b""))


def _frames_strategy():
    return st.lists(st.tuples(st.integers(0, 255), st.integers(0, 65535), st.binary(max_size=300)),
                    min_size=1, max_size=8)


def _feed_chunked(parser: FrameParser, data: bytes, cuts: list[int]) -> list[Frame]:
    out, pos = [], 0
    for c in sorted({c % (len(data) + 1) for c in cuts}) + [len(data)]:
        out += parser.feed(data[pos:c])
        pos = c
    return out + parser.flush()


@settings(max_examples=300, deadline=2000, suppress_health_check=[HealthCheck.too_slow])
@given(st.binary(max_size=5000), st.lists(st.integers(0, 10000), max_size=10))
def test_random_bytes_never_crash_and_are_all_accounted(data, cuts):
    parser = FrameParser()
    frames = _feed_chunked(parser, data, cuts)
    s = parser.stats
    assert s.bytes_in == len(data)
    assert parser.pending == 0
    consumed = sum(10 + len(f.payload) for f in frames)
    assert consumed + s.bytes_skipped == len(data)


@settings(max_examples=300, deadline=2000, suppress_health_check=[HealthCheck.too_slow])
@given(st.binary(max_size=2000), _frames_strategy(), st.binary(max_size=500), st.lists(st.integers(0, 10000), max_size=8))
def test_valid_frames_after_garbage_are_all_recovered(garbage, specs, between, cuts):
    frames = [Frame(t, s, p) for t, s, p in specs]
    data = garbage + b"".join(encode_frame(f.type, f.sequence, f.payload) + between for f in frames)
    got = _feed_chunked(FrameParser(), data, cuts)
    # every frame sent comes back, in order (garbage could only add a frame by passing both CRCs)
    it = iter(got)
    assert all(any(g == f for g in it) for f in frames)


@settings(max_examples=300, deadline=2000, suppress_health_check=[HealthCheck.too_slow])
@given(_frames_strategy(), st.data())
def test_mutated_streams_resynchronise(specs, data):
    frames = [Frame(t, s, p) for t, s, p in specs]
    encoded = [encode_frame(f.type, f.sequence, f.payload) for f in frames]
    hit = data.draw(st.sets(st.integers(0, len(frames) - 1)))
    tails = {}  # truncated frame -> the bytes cut off its end
    for i in hit:  # flip a byte, truncate, or duplicate a slice inside frame i
        b = bytearray(encoded[i])
        kind = data.draw(st.sampled_from(["flip", "truncate", "insert"]))
        pos = data.draw(st.integers(0, len(b) - 1))
        if kind == "flip":
            b[pos] ^= data.draw(st.integers(1, 255))
        elif kind == "truncate":
            tails[i] = bytes(b[pos:])
            del b[pos:]
        else:
            b[pos:pos] = data.draw(st.binary(min_size=1, max_size=20))
        encoded[i] = bytes(b)
    parser = FrameParser()
    got = parser.feed(b"".join(encoded)) + parser.flush()
    # A cut whose lost tail equals the bytes that follow it leaves a stream no parser can tell from the
    # frame whole and the next one missing its head (hypothesis found it: a CRC byte equal to SYNC[0]).
    swallowed = {i + 1 for i, tail in tails.items() if b"".join(encoded[i + 1:]).startswith(tail)}
    intact = [f for i, f in enumerate(frames) if i not in hit and i not in swallowed]
    it = iter(got)
    assert all(any(g == f for g in it) for f in intact)
    if any(encoded[i] for i in hit):  # a damaged frame is noticed, not delivered
        assert parser.stats.crc_errors + parser.stats.header_errors + parser.stats.bytes_skipped > 0


def test_parser_is_linear_on_a_long_hostile_stream():
    # a stream full of false syncs with valid-looking headers: must finish quickly and recover the frame
    fake = b"".join(SYNC + (4000).to_bytes(2, "little") + b"\x01\x00\x00" for _ in range(2000))
    good = encode_frame(2, 7, b"ok")
    parser = FrameParser()
    got = parser.feed(fake + good) + parser.flush()
    assert Frame(2, 7, b"ok") in got


# ---- CAN ------------------------------------------------------------------------------------

def test_dbc_loads_with_fd_block_frames():
    db = cantools.database.load_file(cf.DBC_PATH)
    names = {msg.name: msg for msg in db.messages}
    assert {"MotorCommand", "MotorStatus", "StreamControl", "StreamStatus", "EncoderBlock", "AccelBlock",
            "Event"} <= set(names)
    assert names["AccelBlock"].is_fd and names["AccelBlock"].length == 64
    assert names["EncoderBlock"].is_fd and not names["MotorCommand"].is_fd
    for msg in db.messages:  # every signal fits its frame and ids stay clear of CANopen's set
        assert msg.frame_id < 0x80
        assert max(s.start + s.length for s in msg.signals) <= 8 * msg.length


def test_accel_block_frame_round_trip():
    lsb = cf.accel_lsb(490.33)
    counts = np.arange(-12, 12) * 1000
    block = AccelBlock(123456, 12.345678912, 20000.0, m.counts_to_m_s2(counts, lsb))
    name, values = cf.decode_frame(cf.accel_frame(block, lsb))
    assert name == "AccelBlock"
    assert cf.decode_accel_frame(values, lsb, 20000.0) == block


def test_accel_counts_saturate_at_int16():
    lsb = cf.accel_lsb(100.0)
    block = AccelBlock(0, 0.0, 1e4, np.array([1e6, -1e6, 50.0], np.float32))
    _, values = cf.decode_frame(cf.accel_frame(block, lsb))
    got = cf.decode_accel_frame(values, lsb, 1e4).samples
    np.testing.assert_allclose(got, [32767 * lsb, -100.0, 50.0], rtol=1e-6)


def test_encoder_block_frame_round_trip():
    block = EncoderBlock(7, 1.000000001, 1000.0, np.array([-5, 0, 2**31 - 1, 4, 5, 6, 7, 8, 9, 10], np.int32),
                         np.array([1, 0, 0, 0, 0, 0, 0, 0, 0, 1], bool))
    name, values = cf.decode_frame(cf.encoder_frame(block))
    assert name == "EncoderBlock"
    assert cf.decode_encoder_frame(values, 1000.0) == block
    with pytest.raises(ValueError, match="at most 12"):
        cf.encoder_frame(EncoderBlock(0, 0.0, 1.0, np.zeros(13, np.int32), np.zeros(13, bool)))


def test_motor_command_signals_round_trip():
    msg = cf.encode_frame("MotorCommand", {"Command": 3, "Counter": 9, "TargetSpeed": -6.2832, "Acceleration": 150.5})
    name, values = cf.decode_frame(msg)
    assert name == "MotorCommand" and values["Command"] == 3 and values["Counter"] == 9
    assert values["TargetSpeed"] == pytest.approx(-6.2832) and values["Acceleration"] == pytest.approx(150.5)


def test_eds_loads_as_a_cia402_drive():
    od = canopen.import_od(str(cf.EDS_PATH), node_id=5)
    assert od[0x1000].default == 0x00020192  # CiA 402 device profile
    assert od["Modes of operation"].default == 3 and od[0x6060].index == 0x6060
    for index in (0x6040, 0x6041, 0x60FF, 0x606C, 0x6064, 0x603F):
        assert index in od
    assert od[0x1400][1].default == 0x205 and od[0x1800][1].default == 0x185
    node = canopen.LocalNode(5, od)
    canopen.Network().add_node(node)  # unconnected: PDO maps need a network object to subscribe on
    node.tpdo.read(from_od=True)
    node.rpdo.read(from_od=True)
    assert [v.index for v in node.rpdo[1].map] == [0x6040, 0x60FF]
    assert [v.index for v in node.tpdo[1].map] == [0x6041, 0x606C]
    assert [v.index for v in node.tpdo[2].map] == [0x6064, 0x603F, 0x6061]


def test_a_cut_whose_lost_tail_equals_what_follows_reads_as_the_frame_whole():
    """Frame (100, 12663, b'-') ends in 0xA5, the first sync byte: cut that byte off and the next
    frame's sync completes it. The stream is the frame whole and a next frame without its head, and
    the parser reads it so (the case the mutation test excuses)."""
    first, second = encode_frame(100, 12663, b"-"), encode_frame(0, 0, b"")
    assert first[-1:] == second[:1]
    parser = FrameParser()
    assert parser.feed(first[:-1] + second) + parser.flush() == [Frame(100, 12663, b"-")]
    assert parser.stats.bytes_skipped == len(second) - 1
