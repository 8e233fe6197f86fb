"""poll() on serial ports and topics together (issue 24): a real Uart fed by another Uart.

A port is readable when the RX line goes idle after a burst (IDLE, one character time after the
last byte) or when half of the 64-byte RX DMA ring has filled, whichever first; a long stream
wakes a poller per 32 bytes, never per byte.
"""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from board.kernel import NS_PER_MS, KernelError
from board.uart import RecordingLink, Uart, UartConfig, connect
from firmware.platform.serial import (RX_DMA_HALF_BYTES, SERIAL_TX_BUFFER, SerialError,
                                      SerialPort, open_serial)
from firmware.platform.task import PollWaiter, Task
from firmware.platform.uorb import Subscription
from firmware.platform.workqueue import WorkItem
from tests.fuzzing import fuzz

BAUD = 921_600
CFG = UartConfig(baud=BAUD)
FRAME_NS = CFG.frame_ns_ceil          # the idle time after a burst's last stop bit (10 851 ns)


def idle_ns(t_start_ns: int, nbytes: int) -> int:
    """When IDLE fires for a burst of ``nbytes`` written at ``t_start_ns``."""
    return t_start_ns + CFG.burst_ns(nbytes) + FRAME_NS


@pytest.fixture
def wire(kernel, platform):
    """(peer UART, the board's USART3, a port open on it at 921600 baud)."""
    peer = Uart(kernel, "peer", CFG)
    mine = Uart(kernel, "USART3", UartConfig(baud=57_600))   # the port sets its own baud
    connect(peer, mine)
    return peer, mine, SerialPort(platform, mine, "/dev/ttyS2", BAUD)


def poller(results, items, timeout_ms, kernel, rounds=1):
    """A task's main that polls ``items`` ``rounds`` times, noting (n, ready flags, t_ns)."""
    def main(task):
        for _ in range(rounds):
            n = yield task.poll(items, timeout_ms=timeout_ms)
            results.append((n, tuple(i.updated() for i in items), kernel.now_ns))
    return main


def test_task_wakes_for_a_publication(platform, kernel, wire):
    _, _, port = wire
    orb = platform.orb
    sub = Subscription(orb, "ping_test")
    pub = orb.advertise("ping_test")
    results = []
    Task(platform, "t", poller(results, [sub, port], 100, kernel)).start()
    kernel.call_at(5 * NS_PER_MS, pub.publish, orb.new("ping_test"))
    kernel.run(50 * NS_PER_MS)
    assert results == [(1, (True, False), 5 * NS_PER_MS)]
    assert port.node.callbacks == [] and sub.node.callbacks == []


def test_task_wakes_when_the_line_goes_idle_after_a_burst(platform, kernel, wire):
    peer, _, port = wire
    sub = Subscription(platform.orb, "ping_test")
    results = []
    Task(platform, "t", poller(results, [sub, port], 100, kernel)).start()
    kernel.call_at(2 * NS_PER_MS, peer.write, b"0123456789")
    kernel.run(50 * NS_PER_MS)
    # not at the first byte, not at the last: one character time after the last stop bit
    assert results == [(1, (False, True), idle_ns(2 * NS_PER_MS, 10))]
    assert port.in_waiting == 10 and port.read() == b"0123456789"
    assert not port.updated()


def test_task_wakes_on_timeout_with_n_zero(platform, kernel, wire):
    _, _, port = wire
    sub = Subscription(platform.orb, "ping_test")
    results = []
    kernel.run(3 * NS_PER_MS)
    Task(platform, "t", poller(results, [sub, port], 20, kernel)).start()
    kernel.run(100 * NS_PER_MS)
    assert results == [(0, (False, False), 23 * NS_PER_MS)]


def test_both_ready_count_two(platform, kernel, wire):
    peer, _, port = wire
    orb = platform.orb
    sub = Subscription(orb, "ping_test")
    pub = orb.advertise("ping_test")
    results = []

    def main(task):
        yield task.sleep_us(1000)          # both become ready while the task sleeps
        n = yield task.poll([sub, port], timeout_ms=100)
        results.append((n, kernel.now_ns))
        sub.update()
        port.read()
        n = yield task.poll([port, sub], timeout_ms=100)   # then both within one wake
        results.append((n, kernel.now_ns))

    Task(platform, "t", main).start()
    kernel.call_at(200_000, pub.publish, orb.new("ping_test"))
    kernel.call_at(300_000, peer.write, b"abc")
    t_burst = 5 * NS_PER_MS
    kernel.call_at(t_burst, peer.write, b"xy")
    kernel.call_at(idle_ns(t_burst, 2), pub.publish, orb.new("ping_test"))  # same instant
    kernel.run(20 * NS_PER_MS)
    assert results == [(2, NS_PER_MS), (2, idle_ns(t_burst, 2))]


def test_a_work_items_poll_waiter_wakes_for_bytes_and_topics(platform, kernel, wire):
    peer, _, port = wire
    orb = platform.orb
    pub = orb.advertise("ping_test")
    log = []

    class Reader(WorkItem):
        def __init__(self):
            super().__init__(platform, "reader", "wq:ttyS2")
            self.sub = Subscription(orb, "ping_test")
            self.n = -1

        def arm(self):
            PollWaiter(platform, [self.sub, port], 10_000, self._ready)

        def _ready(self, n):
            self.n = n
            self.schedule_now()

        def run(self):
            got = port.read()
            log.append((self.n, self.sub.update() is not None, got, kernel.now_ns))
            if len(log) < 3:
                self.arm()

    w = Reader()
    w.arm()
    kernel.call_at(1 * NS_PER_MS, peer.write, b"hello")
    kernel.call_at(4 * NS_PER_MS, pub.publish, orb.new("ping_test"))
    kernel.run(30 * NS_PER_MS)
    assert log == [(1, False, b"hello", idle_ns(NS_PER_MS, 5)),
                   (1, True, b"", 4 * NS_PER_MS),
                   (0, False, b"", 14 * NS_PER_MS)]
    assert port.node.callbacks == [] and orb.node("ping_test").callbacks == []


def stream_reader(port, kernel, reads, until_bytes):
    def main(task):
        total = 0
        while total < until_bytes:
            n = yield task.poll([port], timeout_ms=50)
            got = port.read()
            reads.append((n, len(got), kernel.now_ns))
            total += len(got)
            if n == 0:
                return
    return main


def test_a_long_stream_wakes_per_half_ring_not_per_byte(platform, kernel, wire):
    peer, mine, port = wire
    nbytes = 3200
    reads = []
    Task(platform, "reader", stream_reader(port, kernel, reads, nbytes)).start()
    kernel.run(NS_PER_MS)
    events_before = kernel.events_run
    peer.write(bytes(range(256)) * 12 + bytes(128))   # one write of 3200 bytes: 34.7 ms
    kernel.run(100 * NS_PER_MS)
    half = RX_DMA_HALF_BYTES
    assert len(reads) == nbytes // half == 100
    # each wake at the arrival of a half ring's last byte, reading exactly that half
    for i, (n, got, t) in enumerate(reads):
        assert (n, got) == (1, half)
        assert t == NS_PER_MS + CFG.burst_ns((i + 1) * half)
    # kernel events: a few per wake (DMA interrupt, poll resume, task step), none per byte
    events = kernel.events_run - events_before
    assert events < 5 * len(reads) < nbytes
    assert port.wakes == 100 and mine.overruns == 0


def test_a_slow_stream_of_short_bursts_wakes_once_per_burst(platform, kernel, wire):
    peer, _, port = wire
    reads = []
    Task(platform, "reader", stream_reader(port, kernel, reads, 80)).start()
    for k in range(8):                        # 10-byte messages every 2 ms
        kernel.call_at((k + 1) * 2 * NS_PER_MS, peer.write, b"m" * 10)
    kernel.run(30 * NS_PER_MS)
    assert reads == [(1, 10, idle_ns((k + 1) * 2 * NS_PER_MS, 10)) for k in range(8)]


def test_bursts_from_another_process_arrive_a_quantum_late(platform, kernel, wire):
    """Records ``(t_start_ns, config, data)`` as the orchestrator carries them, handed to
    ``receive`` at the next 1 ms quantum: bytes already due arrive at once, the rest on time."""
    _, mine, port = wire
    tap_kernel_uart = Uart(kernel, "remote", CFG)
    tap = RecordingLink()
    tap_kernel_uart.attach(tap)
    reads = []
    Task(platform, "reader", stream_reader(port, kernel, reads, 100)).start()
    kernel.call_at(500_000, tap_kernel_uart.write, bytes(100))    # 1.085 ms long
    kernel.run(NS_PER_MS)
    records = tap.take()
    assert len(records) == 1
    for rec in records:
        mine.receive(*rec)                    # at t = 1 ms: 46 bytes are already due
    kernel.run(5 * NS_PER_MS)
    # 46 bytes are due at delivery: two DMA halves at once (1 ms), then bytes 64 and 96 on
    # time, then IDLE after byte 100
    due_64 = 500_000 + CFG.burst_ns(64)
    due_96 = 500_000 + CFG.burst_ns(96)
    assert reads == [(1, 46, NS_PER_MS), (1, 64 - 46, due_64), (1, 32, due_96),
                     (1, 4, idle_ns(500_000, 100))]


def test_write_accepts_up_to_the_tx_buffer_and_counts_the_rest(platform, kernel, wire):
    peer, _, port = wire
    got = []
    # the reverse direction: the port's bytes reach the peer
    connect(port.uart, peer)
    assert port.room() == SERIAL_TX_BUFFER
    assert port.write(bytes(1500)) == SERIAL_TX_BUFFER
    assert port.tx_dropped == 1500 - SERIAL_TX_BUFFER and port.room() == 0
    assert port.write(b"more") == 0 and port.tx_dropped == 1500 - SERIAL_TX_BUFFER + 4
    kernel.run(20 * NS_PER_MS)
    got.append(peer.read())
    assert len(got[0]) == SERIAL_TX_BUFFER and port.room() == SERIAL_TX_BUFFER


def test_set_baud_reprograms_the_uart(platform, kernel, wire):
    _, mine, port = wire
    assert mine.config.baud == BAUD and port.baud == BAUD
    port.set_baud(115_200)
    assert mine.config.baud == 115_200
    with pytest.raises(SerialError, match="bad baud rate 0"):
        port.set_baud(0)


class _Hw:
    """The one member of board.protocols.BoardHardware that open_serial uses."""

    def __init__(self, uarts):
        self._uarts = uarts

    def uart_by_device(self, device):
        return self._uarts.get(device)


class _System:
    def __init__(self, platform, hw):
        self.platform = platform
        self.hw = hw


def test_open_serial_finds_the_uart_and_refuses_bad_use(platform, kernel):
    usart3 = Uart(kernel, "USART3")
    system = _System(platform, _Hw({"/dev/ttyS2": usart3}))
    port = open_serial(system, "/dev/ttyS2", BAUD)
    assert port.uart is usart3 and usart3.config.baud == BAUD
    with pytest.raises(SerialError, match="no serial device /dev/ttyS9 on this board"):
        open_serial(system, "/dev/ttyS9", BAUD)
    with pytest.raises(SerialError, match="no serial device"):
        open_serial(_System(platform, None), "/dev/ttyS2", BAUD)
    with pytest.raises(SerialError, match="/dev/ttyS2: already open"):
        open_serial(system, "/dev/ttyS2", BAUD)
    port.close()
    for use in (port.read, lambda: port.write(b"x"), port.room, lambda: port.in_waiting):
        with pytest.raises(SerialError, match="/dev/ttyS2: .* on a closed port"):
            use()
    with pytest.raises(SerialError, match="poll on /dev/ttyS2: the port is closed"):
        PollWaiter(platform, [port], 1000, lambda n: None)
    again = open_serial(system, "/dev/ttyS2", 57_600)    # closing freed the UART
    assert again.baud == 57_600


def test_a_task_polling_a_closed_port_or_a_non_file_fails_clearly(platform, kernel, wire):
    _, _, port = wire
    port.close()

    def main(task):
        yield task.poll([port], timeout_ms=10)

    Task(platform, "closed", main).start()
    with pytest.raises(KernelError, match="task closed raised .*SerialError: poll on "
                                          "/dev/ttyS2: the port is closed"):
        kernel.run(NS_PER_MS)

    def main2(task):
        yield task.poll(["/dev/ttyS2"], timeout_ms=10)

    Task(platform, "bad", main2).start()
    with pytest.raises(KernelError, match="TypeError: poll.. waits on Subscriptions and "
                                          "SerialPorts, not '/dev/ttyS2'"):
        kernel.run(2 * NS_PER_MS)


def test_closing_a_port_while_polled_leaves_the_other_items(platform, kernel, wire):
    peer, _, port = wire
    sub = Subscription(platform.orb, "ping_test")
    results = []
    Task(platform, "t", poller(results, [sub, port], 10, kernel)).start()
    kernel.call_at(NS_PER_MS, port.close)
    kernel.call_at(2 * NS_PER_MS, peer.write, b"late")    # no interrupt handlers any more
    kernel.run(30 * NS_PER_MS)
    assert results == [(0, (False, False), 10 * NS_PER_MS)]


def test_on_the_fmu_board_telem2_is_a_pollable_file():
    """The real board: /dev/ttyS2 is USART3 (TELEM2); a peer's bytes wake a task that polls
    the port with a topic, on the board's own kernel and platform."""
    from fmu.board import FmuV2Board
    from firmware.system import System

    board = FmuV2Board(firmware="none")
    system = System(board.platform, hw=board, board=board.spec)
    kernel = board.kernel
    port = open_serial(system, "/dev/ttyS2", BAUD)
    assert port.uart is board.uarts["USART3"] and port.uart.config.baud == BAUD
    with pytest.raises(SerialError, match="no serial device /dev/ttyS7"):
        open_serial(system, "/dev/ttyS7", BAUD)
    # what the board's own firmware holds is refused: nsh's console, the IO link
    with pytest.raises(SerialError, match="/dev/ttyS5 is the board's nsh console"):
        open_serial(system, "/dev/ttyS5", BAUD)
    with pytest.raises(SerialError, match="/dev/ttyS4 is the board's link to the IO"):
        open_serial(system, "/dev/ttyS4", BAUD)
    companion = Uart(kernel, "companion", CFG)
    connect(companion, port.uart)
    connect(port.uart, companion)
    sub = Subscription(board.platform.orb, "ping_test")
    results = []

    def main(task):
        n = yield task.poll([sub, port], timeout_ms=100)
        data = port.read()
        results.append((n, data, kernel.now_ns))
        port.write(data.upper())

    t0 = kernel.now_ns
    Task(board.platform, "echo", main).start()
    kernel.call_at(t0 + NS_PER_MS, companion.write, b"ping")
    kernel.run(t0 + 5 * NS_PER_MS)
    assert results == [(1, b"ping", idle_ns(t0 + NS_PER_MS, 4))]
    assert companion.read() == b"PING"


def test_bytes_through_the_line_decoder_wake_the_same_way(platform, kernel, wire):
    """A peer 1 % fast (930 000 baud) goes through the bit-level decoder, not the fast path:
    still a wake per 32 bytes and one at IDLE for the tail; a break reads as one 0x00."""
    _, mine, port = wire
    fast = Uart(kernel, "fast_peer", UartConfig(baud=930_000))
    connect(fast, mine)
    reads = []
    Task(platform, "reader", stream_reader(port, kernel, reads, 101)).start()
    kernel.call_at(NS_PER_MS, fast.write, bytes(range(100)))
    kernel.call_at(3 * NS_PER_MS, fast.send_break)
    kernel.run(30 * NS_PER_MS)
    assert [(n, got) for n, got, _ in reads] == [(1, 32), (1, 32), (1, 32), (1, 4), (1, 1)]
    sender = UartConfig(baud=930_000)
    bit_ns = 1_000_000_000 // 930_000
    for i, (_, _, t) in enumerate(reads[:3]):      # at the 32nd, 64th, 96th byte's stop bit
        assert abs(t - (NS_PER_MS + sender.burst_ns(32 * (i + 1)))) < bit_ns
    assert reads[3][2] > NS_PER_MS + sender.burst_ns(100)             # IDLE after the tail
    assert 3 * NS_PER_MS < reads[4][2] < 3 * NS_PER_MS + 3 * sender.frame_ns_ceil
    assert mine.breaks == 1


@fuzz(60)
@given(bursts=st.lists(st.tuples(st.integers(0, 3000), st.binary(min_size=1, max_size=200)),
                       min_size=1, max_size=12))
def test_fuzz_whatever_arrives_is_read_in_order_and_wakes_only_when_readable(bursts):
    """Outside bytes in random bursts (gap in us before each, up to 200 bytes): a task polling
    the port and reading what is there gets exactly the bytes sent, in order; every wake with
    n > 0 finds bytes waiting; data wakes are at most one per 32 bytes plus one per burst."""
    from board.kernel import Kernel
    from firmware.platform import Platform

    kernel = Kernel("fuzz")
    platform = Platform(kernel)
    peer = Uart(kernel, "peer", CFG)
    mine = Uart(kernel, "USART3", UartConfig(baud=57_600), rx_buffer_size=4096)
    connect(peer, mine)
    port = SerialPort(platform, mine, "/dev/ttyS2", BAUD)
    got = bytearray()
    wakes = []

    def main(task):
        while True:
            n = yield task.poll([port], timeout_ms=5)
            waiting = port.in_waiting
            wakes.append((n, waiting))
            got.extend(port.read())

    Task(platform, "reader", main).start()
    t = 0
    for gap_us, data in bursts:
        t += gap_us * 1000 + CFG.burst_ns(len(data))  # one burst after the other on the line
        kernel.call_at(t - CFG.burst_ns(len(data)), peer.write, data)
    kernel.run(t + 20 * NS_PER_MS)
    sent = b"".join(data for _, data in bursts)
    assert bytes(got) == sent
    assert all(waiting > 0 for n, waiting in wakes if n > 0)
    data_wakes = sum(1 for n, _ in wakes if n > 0)
    assert data_wakes <= len(sent) // RX_DMA_HALF_BYTES + len(bursts)
