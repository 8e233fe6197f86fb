"""CAN bus: frame lengths with CRC and bit stuffing, timing, arbitration, ACK, fault confinement.

Reference frame lengths come from a small string-based encoder written here independently of
board/can.py (CRC as a long division, stuffing by looking at the last five bits sent).
"""

import can
import pytest

from board.can import (
    CanBus,
    CanController,
    arbitration_key,
    crc15,
    frame_bits,
    frame_length_bits,
    stuffed_length,
)

NS = 10**9
ERR_TAIL = 2 + 14 + 3  # CRC delimiter + ACK slot, error flag + delimiter, interframe space


def msg(aid, data=b"", ext=False, rtr=False, dlc=None):
    return can.Message(arbitration_id=aid, data=data, is_extended_id=ext, is_remote_frame=rtr,
                       dlc=dlc)


# -- independent reference encoder -------------------------------------------------------------

def ref_crc(bits: str) -> str:
    rem = int(bits, 2) << 15
    poly = 0x8000 | 0x4599  # x^15 + x^14 + x^10 + x^8 + x^7 + x^4 + x^3 + 1
    for shift in range(rem.bit_length() - 16, -1, -1):
        if rem >> (shift + 15) & 1:
            rem ^= poly << shift
    return format(rem, "015b")


def ref_length(aid, data=b"", ext=False, rtr=False, dlc=None):
    dlc = len(data) if dlc is None else dlc
    if ext:
        head = "0" + format(aid >> 18, "011b") + "11" + format(aid & 0x3FFFF, "018b")
        head += str(int(rtr)) + "00"
    else:
        head = "0" + format(aid, "011b") + str(int(rtr)) + "00"
    bits = head + format(dlc, "04b") + "".join(format(b, "08b") for b in data)
    bits += ref_crc(bits)
    out = ""
    for ch in bits:
        out += ch
        if out[-5:] in ("00000", "11111"):
            out += "1" if ch == "0" else "0"
    return len(out) + 10  # CRC delimiter, ACK slot, ACK delimiter, 7 EOF bits


# -- frame encoding ------------------------------------------------------------------------------

def test_crc15_check_value():
    bits = [int(c) for c in "".join(format(b, "08b") for b in b"123456789")]
    assert crc15(bits) == 0x059E  # CRC-15/CAN catalogue check value


def test_frame_id0_dlc0_by_hand():
    # SOF, 11 ID bits, RTR, IDE, r0, 4 DLC bits: 19 dominant bits; the CRC of all zeros is 0,
    # so SOF..CRC is 34 zeros. A stuff bit follows zeros number 5, 10, 15, 20, 25 and 30:
    # 34 + 6 = 40 bits, plus 10 for delimiter, ACK, delimiter and EOF = 50.
    m = msg(0x000)
    assert frame_bits(m) == [0] * 34
    assert stuffed_length(frame_bits(m)) == 40
    assert frame_length_bits(m) == 50 == ref_length(0)


def test_minimum_frame_is_44_bits_plus_3_ifs():
    # Without stuffing a standard DLC-0 data frame is 19 + 15 + 10 = 44 bits, the textbook
    # 47 with the interframe space. Every real DLC-0 frame needs at least one stuff bit
    # (RTR, IDE, r0 and DLC 0000 are seven dominant bits in a row).
    assert len(frame_bits(msg(0x555))) + 10 == 44
    assert all(frame_length_bits(msg(i)) > 44 for i in range(0, 0x800, 0x51))
    # A frame that happens to need no stuff bit at all: 19 + 32 + 15 + 10 = 76.
    m = msg(0x555, b"\xaa" * 4)
    assert stuffed_length(frame_bits(m)) == len(frame_bits(m))
    assert frame_length_bits(m) == 76


@pytest.mark.parametrize("aid, data, ext, rtr, dlc", [
    (0x123, b"\xff" * 8, False, False, None),
    (0x123, b"\x00" * 8, False, False, None),
    (0x7FF, b"", False, False, None),
    (0x000, b"\x00" * 8, False, False, None),
    (0x1FFFFFFF, b"\xff" * 8, True, False, None),
    (0x100 << 18, b"\x01\x02", True, False, None),
    (0x0000000, b"", True, False, None),
    (0x2AA, b"", False, True, 4),
    (0x1234567, b"", True, True, 8),
])
def test_frame_lengths_match_reference(aid, data, ext, rtr, dlc):
    assert frame_length_bits(msg(aid, data, ext, rtr, dlc)) == ref_length(aid, data, ext, rtr,
                                                                          dlc)


def test_extended_frame_unstuffed_is_64_plus_data():
    assert len(frame_bits(msg(0x1555555, ext=True))) + 10 == 64
    assert len(frame_bits(msg(0x1555555, bytes(8), ext=True))) + 10 == 128


def test_arbitration_key_order():
    std_100 = arbitration_key(msg(0x100))
    std_100_rtr = arbitration_key(msg(0x100, rtr=True, dlc=0))
    ext_100 = arbitration_key(msg(0x100 << 18, ext=True))
    std_101 = arbitration_key(msg(0x101))
    assert std_100 < std_100_rtr < ext_100 < std_101


# -- timing and arbitration ------------------------------------------------------------------

def listener(ctrl):
    got = []

    def isr(t):
        m = ctrl.recv()
        got.append((t, m.arbitration_id, m.is_extended_id, bytes(m.data)))

    ctrl.on_receive(isr)
    return got


@pytest.mark.parametrize("bitrate", [1_000_000, 500_000, 83_333])
def test_delivery_time_is_frame_bits_over_bitrate(kernel, bitrate):
    bus = CanBus(kernel, "can1", bitrate)
    a, b = CanController(bus, "a"), CanController(bus, "b")
    got = listener(b)
    done = []
    a.on_tx_complete(lambda t, m, ok: done.append((t, ok)))
    m = msg(0x555, b"\xaa" * 4)
    kernel.call_at(1000, a.send, m)
    kernel.run(NS)
    t_end = 1000 + (76 * NS) // bitrate
    assert got == [(t_end, 0x555, False, b"\xaa" * 4)]
    assert done == [(t_end, True)]
    assert bus.idle_ns == 1000 + (79 * NS) // bitrate
    assert a.rx_pending == 0  # a sender does not receive its own frame
    assert bus.frames == 1 and bus.error_frames == 0


def test_received_message_fields(kernel):
    bus = CanBus(kernel, "can1")
    a, b = CanController(bus, "a"), CanController(bus, "b")
    a.send(msg(0x1ABCDE, b"\x01\x02\x03", ext=True))
    kernel.run(NS)
    m = b.recv()
    assert (m.arbitration_id, m.is_extended_id, bytes(m.data), m.dlc) == (
        0x1ABCDE, True, b"\x01\x02\x03", 3)
    assert m.is_rx and m.channel == "b"
    assert m.timestamp == frame_length_bits(m) * 1000 / 1e9
    assert b.recv() is None


def test_same_instant_arbitration_lowest_id_first(kernel):
    bus = CanBus(kernel, "can1")
    a, b, c, d = (CanController(bus, n) for n in "abcd")
    got = listener(d)
    frames = {
        "a": msg(0x101, b"\x01"),
        "b": msg((0x100 << 18) | 0x5, b"\x02", ext=True),  # extended, base ID 0x100
        "c": msg(0x100, b"\x03"),
    }
    # Queued by different contexts in the same nanosecond.
    kernel.call_at(10_000, a.send, frames["a"], priority=100)
    kernel.call_at(10_000, b.send, frames["b"], priority=-10)
    kernel.call_at(10_000, c.send, frames["c"], priority=0)
    kernel.run(NS)
    n_c, n_b, n_a = (frame_length_bits(frames[k]) for k in "cba")
    t_c = 10_000 + n_c * 1000
    t_b = t_c + (3 + n_b) * 1000
    t_a = t_b + (3 + n_a) * 1000
    assert got == [(t_c, 0x100, False, b"\x03"), (t_b, (0x100 << 18) | 5, True, b"\x02"),
                   (t_a, 0x101, False, b"\x01")]


def test_loser_retries_at_next_idle_and_late_frame_waits(kernel):
    bus = CanBus(kernel, "can1")
    a, b, c = (CanController(bus, n) for n in "abc")
    got = listener(c)
    kernel.call_at(0, a.send, msg(0x200))
    kernel.call_at(1, b.send, msg(0x001))  # bus already busy: waits, then wins the next round
    kernel.call_at(2, a.send, msg(0x300))
    kernel.run(NS)
    assert [aid for _, aid, _, _ in got] == [0x200, 0x001, 0x300]


def test_mailboxes_full_and_lowest_id_first(kernel):
    bus = CanBus(kernel, "can1")
    a, b = CanController(bus, "a"), CanController(bus, "b")
    got = listener(b)
    assert all(a.send(msg(i)) for i in (0x300, 0x200, 0x100))
    assert a.send(msg(0x050)) is False
    assert a.tx_pending == 3
    kernel.run(NS)
    assert [aid for _, aid, _, _ in got] == [0x100, 0x200, 0x300]
    assert a.tx_pending == 0 and a.tx_frames == 3


def test_rx_fifo_overrun(kernel):
    bus = CanBus(kernel, "can1")
    a = CanController(bus, "a")
    b = CanController(bus, "b", rx_fifo_depth=2)
    locked = CanController(bus, "c", rx_fifo_depth=2, rx_fifo_locked=True)
    for i in (1, 2, 3):
        a.send(msg(i))
    kernel.run(NS)
    assert b.overruns == 1 and locked.overruns == 1
    assert [b.recv().arbitration_id for _ in range(2)] == [1, 3]  # newest overwritten
    assert [locked.recv().arbitration_id for _ in range(2)] == [1, 2]  # incoming dropped


def test_loopback_receives_own_frames_without_ack(kernel):
    bus = CanBus(kernel, "can1")
    a = CanController(bus, "a", loopback=True)
    a.send(msg(0x42, b"x"))
    kernel.run(NS)
    assert a.recv().arbitration_id == 0x42
    assert a.tec == 0 and bus.error_frames == 0


# -- errors -----------------------------------------------------------------------------------

def test_lone_node_ack_errors_to_error_passive(kernel):
    bus = CanBus(kernel, "can1")
    a = CanController(bus, "a")
    m = msg(0x123, b"\x11\x22")
    a.send(m)
    err_at = frame_length_bits(m) - 10 + 2
    period = err_at + 14 + 3
    for k in range(1, 17):
        kernel.run(((k - 1) * period + err_at) * 1000 - 1)
        assert a.tec == 8 * (k - 1)
        kernel.run(((k - 1) * period + err_at) * 1000)
        assert a.tec == 8 * k
        assert a.state == ("error_passive" if k == 16 else "error_active")
    # Error passive: an ACK error no longer counts, and the node waits 8 more bits each time.
    kernel.run((16 * period + 3 * (period + 8)) * 1000)
    assert a.tec == 128 and a.state == "error_passive"
    assert bus.error_frames == 19 and a.tx_errors == 19
    assert a.tx_pending == 1 and bus.frames == 0


def test_no_auto_retransmit_gives_up_after_one_attempt(kernel):
    bus = CanBus(kernel, "can1")
    a = CanController(bus, "a", auto_retransmit=False)
    done = []
    a.on_tx_complete(lambda t, m, ok: done.append(ok))
    a.send(msg(0x10))
    kernel.run(NS)
    assert done == [False] and a.tec == 8 and bus.error_frames == 1


def test_injected_errors_are_counted_and_retransmitted(kernel):
    bus = CanBus(kernel, "can1")
    a, b = CanController(bus, "a"), CanController(bus, "b")
    got = listener(b)
    m = msg(0x321, b"\xde\xad")
    bus.inject_errors(3)
    a.send(m)
    kernel.run(NS)
    n = frame_length_bits(m)
    assert got == [((3 * (n - 10 + ERR_TAIL) + n) * 1000, 0x321, False, b"\xde\xad")]
    assert bus.error_frames == 3 and bus.frames == 1
    assert a.tec == 3 * 8 - 1 and b.rec == 3 - 1
    assert a.tx_errors == 3


def test_bus_off_after_32_transmit_errors_then_auto_recovery(kernel):
    bus = CanBus(kernel, "can1")
    a, b = CanController(bus, "a"), CanController(bus, "b")
    got = listener(b)
    m = msg(0x0F0, b"\x55")
    n = frame_length_bits(m)
    period = n - 10 + ERR_TAIL
    bus.inject_errors(32)
    a.send(m)
    # Attempts 16..31 start after an error-passive suspend of 8 bits.
    t_off = (31 * period + 16 * 8 + n - 10 + 2) * 1000
    kernel.run(t_off - 1)
    assert a.tec == 248 and a.state == "error_passive"
    kernel.run(t_off)
    assert a.state == "bus_off" and a.tec == 256 and a.bus_off_count == 1
    assert b.rec == 32 and b.state == "error_active"
    t_rec = t_off + 128 * 11 * 1000
    kernel.run(t_rec - 1)
    assert a.state == "bus_off" and got == []
    kernel.run(NS)
    assert a.state == "error_active"
    assert got == [(t_rec + n * 1000, 0x0F0, False, b"\x55")]
    assert bus.error_frames == 32


def test_forced_bus_off_needs_recover_without_auto_recovery(kernel):
    bus = CanBus(kernel, "can1")
    a = CanController(bus, "a")
    b = CanController(bus, "b", auto_recovery=False)
    got = listener(b)
    bus.force_bus_off(b)
    assert b.state == "bus_off"
    a.send(msg(0x7))
    kernel.run(1_000_000)
    assert got == [] and a.tec == 8 * 16  # nobody left to ACK
    b.recover()
    kernel.run(1_000_000 + 128 * 11 * 1000)
    assert b.state == "error_active"
    kernel.run(NS)
    assert [aid for _, aid, _, _ in got] == [0x7]


# -- bad input ------------------------------------------------------------------------------------

def test_bad_arguments_raise(kernel):
    with pytest.raises(ValueError, match="bitrate"):
        CanBus(kernel, "can1", 0)
    with pytest.raises(ValueError, match="bitrate"):
        CanBus(kernel, "can1", 2_000_000)
    bus = CanBus(kernel, "can1")
    a = CanController(bus, "a")
    with pytest.raises(ValueError, match="standard arbitration id"):
        a.send(msg(0x800))
    with pytest.raises(ValueError, match="DLC"):
        a.send(can.Message(arbitration_id=1, is_extended_id=False, data=b"ab", dlc=3))
    with pytest.raises(ValueError, match="rx_fifo_depth"):
        CanController(bus, "x", rx_fifo_depth=0)
    with pytest.raises(ValueError, match="inject_errors"):
        bus.inject_errors(-1)


# -- wire faults, sleep mode, error interrupts ------------------------------------------------------

SHORT_ATTEMPT = 1 + 14 + 3  # SOF read back recessive, error flag + delimiter, interframe space


def test_short_drives_the_sender_bus_off_in_32_attempts_receivers_untouched(kernel):
    bus = CanBus(kernel, "can1")
    a, b = CanController(bus, "a"), CanController(bus, "b")
    got = listener(b)
    errs = []
    a.on_error(lambda t, state: errs.append((t, state)))
    bus.set_wire_fault(short=True)
    a.send(msg(0x0F0, b"\x55"))
    # 16 attempts while error active, 16 more each after an 8-bit suspend; the 32nd error
    # (TEC 256) is detected at its SOF bit
    t_passive = (15 * SHORT_ATTEMPT + 1) * 1000
    t_off = (31 * SHORT_ATTEMPT + 16 * 8 + 1) * 1000
    kernel.run(t_off - 1)
    assert a.state == "error_passive" and a.tec == 248 and a.tx_errors == 31
    kernel.run(t_off)
    assert a.state == "bus_off" and a.bus_off_count == 1
    assert errs == [(t_passive, "error_passive"), (t_off, "bus_off")]
    assert b.rec == 0 and b.state == "error_active" and got == []  # an idle bus to them
    # the short is recessive: recovery completes, the frame fails again
    kernel.run(t_off + 128 * 11 * 1000)
    assert a.state == "error_active" and a.tec == 0
    kernel.run(t_off + 128 * 11 * 1000 + t_off)
    assert a.bus_off_count == 2 and got == []
    # mended: the next recovery sends the frame
    bus.set_wire_fault()
    kernel.run(NS)
    assert [aid for _, aid, _, _ in got] == [0x0F0] and a.state == "error_active"


def test_bit_error_rate_is_seeded_counts_both_sides_and_can_reach_bus_off(kernel):
    def run(seed, ber, n_frames):
        k = type(kernel)()
        bus = CanBus(k, "can1")
        a, b = CanController(bus, "a"), CanController(bus, "b")
        got = listener(b)
        bus.set_wire_fault(bit_error_rate=ber, seed=seed)
        for i in range(n_frames):
            k.call_at(i * 1_000_000, a.send, msg(0x100 + i % 3, bytes(8)))
        k.run(n_frames * 1_000_000 + 10_000_000)
        return a, b, bus, got

    a1, b1, bus1, got1 = run(5, 5e-4, 200)
    a2, _, _, got2 = run(5, 5e-4, 200)
    assert got1 == got2 and a1.tx_errors == a2.tx_errors  # same seed, same errors
    _, _, _, got3 = run(6, 5e-4, 200)
    assert [t for t, *_ in got3] != [t for t, *_ in got1]  # another seed, other errors
    # ~130 bits per frame: ~6 % of the attempts fail; every one retried and delivered once
    assert 3 < a1.tx_errors < 30 and len(got1) == 200 and a1.state == "error_active"
    assert bus1.error_frames == a1.tx_errors
    # a heavy rate: most attempts fail, TEC climbs 8 per error and 1 per success
    a3, _, _, _ = run(5, 0.05, 5)
    assert a3.bus_off_count >= 1
    with pytest.raises(ValueError, match="bit_error_rate"):
        CanBus(kernel, "x").set_wire_fault(bit_error_rate=1.5)


def test_controller_in_sleep_mode_is_off_the_bus_until_enabled(kernel):
    bus = CanBus(kernel, "can1")
    a = CanController(bus, "a")
    b = CanController(bus, "b", enabled=False)
    got = listener(b)
    b.send(msg(0x55))
    a.send(msg(0x7))
    kernel.run(1_000_000)
    assert got == [] and a.state == "error_passive"  # nobody ACKs; b sends nothing
    assert b.tx_frames == 0 and b.tec == 0
    b.enable()
    kernel.run(NS)
    assert b.tx_frames == 1 and a.tx_frames == 1
    assert [aid for _, aid, _, _ in got] == [0x7]
