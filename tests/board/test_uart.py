"""UART wire: exact byte timing, IDLE, buffers, errors, and what a wrong line format does.

Expected values for mismatched formats are worked out by hand in the comments (sample points at
the centre of each receiver bit, measured from the falling edge of the start bit).
"""

import pytest

from board.kernel import Kernel
from board.uart import (
    BREAK,
    FE,
    LBD,
    ORE,
    PE,
    RecordingLink,
    Uart,
    UartConfig,
    UartWire,
    connect,
)

S = 10**9
SBUS = UartConfig(baud=100_000, data_bits=8, parity="E", stop_bits=2, invert=True)
FAST = UartConfig(baud=1_500_000)


def pair(kernel, tx_cfg, rx_cfg=None, **rx_kw):
    a = Uart(kernel, "a", tx_cfg)
    b = Uart(kernel, "b", rx_cfg or tx_cfg, **rx_kw)
    UartWire(a, b)
    return a, b


def collect_rx(uart):
    got = []
    uart.on_rx(lambda t, v, f: got.append((t, v, f)))
    return got


# -- timing ------------------------------------------------------------------------------------

def test_sbus_frame_complete_exactly_3ms_after_write(kernel):
    a, b = pair(kernel, SBUS)
    kernel.run(1_000_000)
    frame = bytes([0x0F] + list(range(1, 24)) + [0x00])
    a.write(frame)
    kernel.run(1_000_000 + 3_000_000 - 1)
    assert b.in_waiting == 24
    kernel.run(1_000_000 + 3_000_000)
    assert b.read() == frame
    assert b.take_errors() == 0
    assert a.tx_idle_ns == 4_000_000


def test_byte_arrival_times_at_1500000_baud(kernel):
    a, b = pair(kernel, FAST)
    got = collect_rx(b)
    a.write(bytes(range(100)))
    kernel.run(S)
    times = [t for t, _, _ in got]
    assert times[:4] == [6666, 13333, 20000, 26666]
    assert times == [((i + 1) * 10 * S) // 1_500_000 for i in range(100)]
    assert [v for _, v, _ in got] == list(range(100))
    assert b.in_waiting == 0  # the RXNE handler read every byte


def test_lazy_reads_see_exactly_the_arrived_bytes(kernel):
    a, b = pair(kernel, FAST)
    a.write(bytes(range(68)))
    for i in (0, 9, 40, 67):
        t = ((i + 1) * 10 * S) // 1_500_000
        kernel.run(t - 1)
        assert b.in_waiting == i
        kernel.run(t)
        assert b.in_waiting == i + 1
    assert b.read() == bytes(range(68))
    assert b.rx_bytes == 68


def test_read_from_inside_a_context_uses_context_time(kernel):
    a, b = pair(kernel, FAST)
    a.write(b"xyz")
    seen = []

    def task():
        kernel.busy_ns = 13_333  # as if blocked on a bus for that long
        seen.append(b.read())

    kernel.call_at(0, task)
    kernel.run(100)
    assert seen == [b"xy"]


def test_idle_fires_one_character_after_last_byte(kernel):
    a, b = pair(kernel, FAST)
    events = []
    b.on_idle(lambda t: events.append((t, b.read(), kernel.in_isr)))
    a.write(bytes(68))
    kernel.run(S)
    last = (68 * 10 * S) // 1_500_000
    assert events == [(last + 6667, bytes(68), True)]  # 6666.67 ns rounded up


def test_back_to_back_writes_give_one_idle(kernel):
    a, b = pair(kernel, FAST)
    events = []
    b.on_idle(lambda t: events.append((t, len(b.read()))))
    a.write(bytes(10))
    kernel.call_at(30_000, a.write, bytes(5))  # while the first burst is still on the wire
    kernel.run(S)
    end = (10 * 10 * S) // 1_500_000 + (5 * 10 * S) // 1_500_000
    assert events == [(end + 6667, 15)]


def test_transmitter_queues_bursts_and_hands_each_write_once(kernel):
    a = Uart(kernel, "a", UartConfig(115_200))
    link = RecordingLink()
    a.attach(link)
    done = []
    a.on_tx_complete(lambda t: done.append(t))
    assert a.write(b"hello") == 5
    assert a.write(bytearray(b"!!")) == 2
    first_end = (5 * 10 * S) // 115_200
    assert [(t, d) for t, _, d in link.bursts] == [(0, b"hello"), (first_end, b"!!")]
    assert a.tx_busy and a.tx_pending == 7
    assert a.tx_idle_ns == first_end + (2 * 10 * S) // 115_200
    kernel.run(S)
    assert done == [a.tx_idle_ns]
    assert not a.tx_busy and a.tx_pending == 0


def test_tx_buffer_limit_accepts_what_fits(kernel):
    a = Uart(kernel, "a", UartConfig(115_200), tx_buffer_size=8)
    assert a.write(bytes(6)) == 6
    assert a.write(bytes(6)) == 2
    kernel.run((3 * 10 * S) // 115_200)  # three bytes have left the transmitter
    assert a.tx_pending == 5
    assert a.write(bytes(6)) == 3


# -- receive buffer, overrun, break --------------------------------------------------------------

def test_overrun_loses_exactly_the_bytes_beyond_the_buffer(kernel):
    a, b = pair(kernel, FAST, rx_buffer_size=16)
    a.write(bytes(range(20)))
    kernel.run(S)
    assert b.in_waiting == 16
    assert b.overrun
    assert b.read() == bytes(range(16))
    assert b.overruns == 4
    assert b.take_errors() == ORE
    assert not b.overrun
    assert b.overruns == 4


def test_reading_in_time_avoids_overrun(kernel):
    a, b = pair(kernel, FAST, rx_buffer_size=16)
    a.write(bytes(range(20)))
    kernel.run((10 * 10 * S) // 1_500_000)
    assert b.read() == bytes(range(10))
    kernel.run(S)
    assert b.read() == bytes(range(10, 20))
    assert b.overruns == 0 and not b.overrun


def test_break_is_received_as_zero_with_framing_error_and_break(kernel):
    cfg = UartConfig(1_500_000, 8, "E", 1)
    a, b = pair(kernel, cfg)
    idles = []
    b.on_idle(idles.append)
    a.send_break()
    assert a.tx_idle_ns == (12 * S) // 1_500_000  # 11 bits of space + 1 stop bit
    kernel.run(S)
    assert b.read() == b"\x00"
    assert b.break_detected and b.framing_error
    assert (b.breaks, b.framing_errors) == (1, 1)
    assert b.take_errors() == FE | LBD
    assert idles == [(11 * S) // 1_500_000 + -(-11 * S // 1_500_000)]


def test_break_marker_goes_through_the_link(kernel):
    a = Uart(kernel, "a", FAST)
    link = RecordingLink()
    a.attach(link)
    a.write(b"ab")
    a.send_break()
    assert [d for _, _, d in link.bursts] == [b"ab", BREAK]
    assert link.bursts[1][0] == (2 * 10 * S) // 1_500_000


# -- late (cross-process) delivery ----------------------------------------------------------------

def test_late_burst_arrives_now_in_order():
    ka, kb = Kernel("fmu"), Kernel("io")
    ka.run(500_000)
    kb.run(1_000_000)  # the receiver is one quantum ahead
    cfg = UartConfig(115_200)
    a, b = Uart(ka, "a", cfg), Uart(kb, "b", cfg)
    link = RecordingLink()
    a.attach(link)
    a.write(bytes(range(10)))
    got = collect_rx(b)
    for burst in link.take():
        b.receive(*burst)
    kb.run(2_000_000)
    on_time = [500_000 + ((i + 1) * 10 * S) // 115_200 for i in range(10)]
    assert on_time[4] < 1_000_000 < on_time[5]
    assert [t for t, _, _ in got] == [1_000_000] * 5 + on_time[5:]
    assert [v for _, v, _ in got] == list(range(10))


def test_late_burst_lazy_read():
    kb = Kernel("io")
    kb.run(1_000_000)
    cfg = UartConfig(115_200)
    b = Uart(kb, "b", cfg)
    b.receive(500_000, cfg, bytes(range(10)))
    assert b.read() == bytes(range(5))
    kb.run(1_100_000)
    assert b.read() == bytes([5])


# -- line format mismatches ---------------------------------------------------------------

def test_57600_sent_115200_received(kernel):
    # One tx bit = two rx bits; rx samples fall at 0.25, 0.75, 1.25 ... tx bits after the edge.
    # 0x55 on the wire: start 0, then 1 0 1 0 1 0 1 0, stop 1 (tx bits 0..9).
    # Frame 1: data samples at tx bits 0,1,1,2,2,3,3,4 -> 0 1 1 0 0 1 1 0 -> 0x66; stop sample
    #   at 4.75 -> tx bit 4 = 0 -> framing error. It arrives 10 rx bits = 5 tx bits after the edge.
    # Next falling edge after 4.75: tx bit 6. Data samples at tx bits 6,7,7,8,8,9,9,10(idle)
    #   -> 0 1 1 0 0 1 1 1 -> 0xE6; stop sample at 10.75 is idle mark: no error. Arrives at
    #   tx bit 6 + 5 = 11.
    a, b = pair(kernel, UartConfig(57_600), UartConfig(115_200))
    got = collect_rx(b)
    a.write(b"\x55")
    kernel.run(S)
    assert got == [((5 * S) // 57_600, 0x66, FE), ((11 * S) // 57_600, 0xE6, 0)]
    assert b.framing_errors == 1 and b.framing_error


def test_115200_sent_100000_received(kernel):
    # One rx bit = 1.152 tx bits; samples at 0.576, 1.728, 2.88, 4.03, 5.18, 6.34, 7.49, 8.64,
    # 9.79, 10.94 tx bits. Sending 00 00 back to back: data = tx bits 1,2,4,5,6,7,8,9 ->
    # 0 0 0 0 0 0 0 1 (tx bit 9 is the stop bit) -> 0x80; the stop sample hits tx bit 10, the
    # second start bit -> framing error. Nothing after that sample has a falling edge, so the
    # second byte vanishes.
    a, b = pair(kernel, UartConfig(115_200), UartConfig(100_000))
    a.write(b"\x00\x00")
    kernel.run(S)
    assert b.read() == b"\x80"
    assert b.take_errors() == FE
    assert b.framing_errors == 1


def test_back_to_back_writes_decode_as_one_line(kernel):
    a, b = pair(kernel, UartConfig(115_200), UartConfig(100_000))
    a.write(b"\x00")
    a.write(b"\x00")  # queued behind the first: contiguous on the wire
    kernel.run(S)
    assert b.read() == b"\x80"
    assert b.framing_errors == 1


def test_115200_sent_57600_received(kernel):
    # One rx bit = two tx bits: samples at tx bits 1, 3, 5 ... 19 after the edge (exactly on
    # tx bit boundaries, where the later bit is read). 0x00 alone: data samples at tx bits
    # 3,5,7 (data 0) and 9..17 (stop, idle: 1) -> 0xF8; the stop sample (bit 19) is idle: ok.
    # Then 0x00 and another 0x00 15 tx bits later: the second one's start and data bits land
    # on samples 15, 17 and 19 -> data 0 0 0 1 1 1 0 0 = 0x38 and a framing error. The next
    # falling edge after the stop sample never comes: the second byte vanishes.
    a, b = pair(kernel, UartConfig(115_200), UartConfig(57_600))
    got = collect_rx(b)
    a.write(b"\x00")
    kernel.run(S // 100)
    assert [v for _, v, _ in got] == [0xF8] and b.framing_errors == 0
    t1 = kernel.now_ns
    a.write(b"\x00")
    kernel.call_at(t1 + (15 * S) // 115_200, a.write, b"\x00")
    kernel.run(S)
    assert [(t - t1, v, f) for t, v, f in got[1:]] == [((20 * S) // 115_200, 0x38, FE)]
    assert b.framing_errors == 1 and b.take_errors() == FE


def test_100000_sent_115200_received_sbus_like(kernel):
    tx = UartConfig(100_000, 8, "E", 2)
    rx = UartConfig(115_200, 8, "E", 2)
    a, b = pair(kernel, tx, rx)
    got = collect_rx(b)
    sent = bytes([0x0F, 0x00, 0x80, 0x3C, 0x00, 0x00])
    a.write(sent)
    kernel.run(S)
    assert bytes(v for _, v, _ in got) != sent
    errors = sum(1 for _, _, f in got if f & (FE | PE))
    assert errors >= 1
    assert b.framing_errors + b.parity_errors >= errors


def test_parity_mismatch_gives_parity_errors(kernel):
    a, b = pair(kernel, UartConfig(100_000, 8, "E", 1), UartConfig(100_000, 8, "O", 1))
    a.write(b"\x01\x02\x03")
    kernel.run(S)
    assert b.read() == b"\x01\x02\x03"
    assert b.parity_errors == 3 and b.framing_errors == 0
    assert b.take_errors() == PE


def test_no_parity_sent_even_parity_expected(kernel):
    # 0x01 sent 8N1, received 8E1: the stop bit (1) is read as parity (expected 1 for one set
    # bit: fine), then the stop sample falls on the idle line (mark): no error for a lone byte.
    # 0x03 has even parity 0, so the stop bit read as parity is wrong -> PE.
    a, b = pair(kernel, UartConfig(9600, 8, "N", 1), UartConfig(9600, 8, "E", 1))
    got = collect_rx(b)
    a.write(b"\x01")
    kernel.run(S // 10)
    a.write(b"\x03")
    kernel.run(S)
    assert got[0][1:] == (0x01, 0)
    assert got[1][1:] == (0x03, PE)


def test_inversion_mismatch_reads_breaks_and_never_idles(kernel):
    # Inverted transmitter, plain receiver: the idle line looks like space, the start bit like
    # mark; the stop bit is the first high->low edge the receiver sees, followed by space
    # forever: an all-space frame (0x00, framing error, break).
    a, b = pair(kernel, UartConfig(100_000, invert=True), UartConfig(100_000))
    idles = []
    b.on_idle(idles.append)
    a.write(b"\x00")
    kernel.run(S)
    assert b.read() == b"\x00"
    assert b.take_errors() == FE | LBD
    assert b.breaks == 1
    assert idles == []


def test_inverted_sbus_into_plain_receiver_is_garbage(kernel):
    a, b = pair(kernel, SBUS, UartConfig(100_000, 8, "E", 2))
    a.write(bytes([0x0F, 0x12, 0x34, 0x56]))
    kernel.run(S)
    assert b.read() != bytes([0x0F, 0x12, 0x34, 0x56])
    assert b.framing_errors + b.parity_errors >= 1


def test_two_stop_bits_sent_one_expected_reads_right(kernel):
    a, b = pair(kernel, UartConfig(100_000, 8, "E", 2), UartConfig(100_000, 8, "E", 1))
    a.write(bytes(range(25)))
    kernel.run(S)
    assert b.read() == bytes(range(25))
    assert b.take_errors() == 0


def test_one_stop_bit_sent_two_expected_reads_right(kernel):
    # The STM32 checks only the first stop bit, so back-to-back 8E1 frames still decode.
    a, b = pair(kernel, UartConfig(100_000, 8, "E", 1), UartConfig(100_000, 8, "E", 2))
    a.write(bytes(range(25)))
    kernel.run(S)
    assert b.read() == bytes(range(25))
    assert b.take_errors() == 0


def test_seven_data_bits_drop_bit_seven(kernel):
    cfg = UartConfig(9600, 7, "E", 1)
    a, b = pair(kernel, cfg)
    a.write(b"\xc1")
    kernel.run(S)
    assert b.read() == b"\x41"


def test_one_way_connect(kernel):
    a, b = Uart(kernel, "a", FAST), Uart(kernel, "b", FAST)
    connect(a, b)
    a.write(b"hi")
    b.write(b"ho")
    kernel.run(S)
    assert b.read() == b"hi" and a.read() == b""


# -- configuration errors -----------------------------------------------------------------

@pytest.mark.parametrize("kwargs, word", [
    ({"baud": 0}, "baud"),
    ({"baud": 115200.0}, "baud"),
    ({"data_bits": 6}, "data_bits"),
    ({"parity": "X"}, "parity"),
    ({"stop_bits": 3}, "stop_bits"),
    ({"invert": 1}, "invert"),
])
def test_bad_config_raises(kwargs, word):
    with pytest.raises(ValueError, match=word):
        UartConfig(**kwargs)


def test_bad_uart_arguments_raise(kernel):
    with pytest.raises(ValueError, match="rx_buffer_size"):
        Uart(kernel, "u", rx_buffer_size=0)
    with pytest.raises(TypeError, match="config"):
        Uart(kernel, "u", config="115200 8N1")


def test_idle_after_mismatched_burst(kernel):
    # Same line as test_57600_sent_115200_received: the last word arrives at 11 tx bits, the
    # last space bit of the burst ends at 9 tx bits; IDLE needs one rx character (86805.6 ns,
    # rounded up) of mark after both.
    a, b = pair(kernel, UartConfig(57_600), UartConfig(115_200))
    idles = []
    b.on_idle(idles.append)
    a.write(b"\x55")
    kernel.run(S)
    assert idles == [(11 * S) // 57_600 + 86_806]
    assert b.read() == b"\x66\xe6"
