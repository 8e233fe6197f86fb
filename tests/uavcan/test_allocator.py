"""The FMU's node-ID allocation server as the DroneCAN spec's centralised allocator: parts of
the unique ID echoed, a stale follow-up restarts, the requested ID or the nearest free one,
the same ID again for the same unique ID, silence when the network is full."""

from __future__ import annotations

from firmware.drivers.uavcan.allocator import Allocator

UID = bytes(range(0x10, 0x20))


def _allocate(a, uid, requested=0, t_us=0):
    assert a.handle(True, uid[:6], requested, t_us) == (0, uid[:6])
    assert a.handle(False, uid[6:12], requested, t_us + 100_000) == (0, uid[:12])
    return a.handle(False, uid[12:], requested, t_us + 200_000)


def test_three_stages_then_an_id_from_125_down_and_the_same_again():
    taken = {125}
    a = Allocator(1, lambda: taken)
    assert _allocate(a, UID) == (124, UID)  # 125 is a node heard on the bus
    other = bytes(16)
    assert _allocate(a, other, t_us=1_000_000) == (123, other)
    assert _allocate(a, UID, t_us=2_000_000) == (124, UID)  # the table remembers it
    assert a.allocations == 3 and a.table == {UID: 124, other: 123}


def test_requested_id_or_the_next_free_one_up_then_down():
    a = Allocator(1, lambda: {50, 51})
    assert _allocate(a, UID, requested=60) == (60, UID)
    assert _allocate(a, bytes(16), requested=50, t_us=1_000_000) == (52, bytes(16))
    full = Allocator(1, lambda: set(range(2, 126)) - {7})
    assert _allocate(full, UID, requested=120) == (7, UID)  # nothing above: search down


def test_stale_or_orphan_follow_ups_restart_and_a_full_network_gets_no_answer():
    a = Allocator(1, lambda: set())
    assert a.handle(False, UID[6:12], 0, 0) is None  # no first part seen
    assert a.handle(True, UID[:6], 0, 0) == (0, UID[:6])
    assert a.handle(False, UID[6:12], 0, 600_000) is None  # later than 500 ms: start over
    assert a.restarts == 2
    assert a.handle(True, b"", 0, 0) is None and a.handle(True, bytes(7), 0, 0) is None
    full = Allocator(1, lambda: set(range(2, 126)))
    assert _allocate(full, UID) is None and full.table == {}
