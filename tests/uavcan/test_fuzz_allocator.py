"""Fuzzing the FMU's dynamic node-ID allocation server with what anonymous nodes on the bus may
send: first parts and follow-ups of any length, any requested ID, at any time, interleaved."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from firmware.drivers.uavcan.allocator import MAX_NODE_ID, UID_LEN, Allocator
from tests.fuzzing import fuzz

request = st.tuples(st.booleans(), st.binary(max_size=8), st.integers(-5, 200),
                    st.integers(0, 2_000_000))


@fuzz(examples=300)
@given(requests=st.lists(request, max_size=40), heard=st.sets(st.integers(0, 127), max_size=20))
def test_allocator_answers_within_the_protocol(requests, heard):
    """Whatever arrives: an answer is None, a partial unique ID (node 0) no longer than 16
    bytes, or a valid node ID (1..125) that is not the FMU's, not one heard on the bus, and
    never given to two unique IDs; a unique ID asking again gets its ID back."""
    alloc = Allocator(own_id=1, occupied=lambda: set(heard))
    now = 0
    given_to: dict[int, bytes] = {}
    for first, part, requested, dt in requests:
        now += dt
        answer = alloc.handle(first, part, requested, now)
        if answer is None:
            continue
        node_id, uid = answer
        if node_id == 0:
            assert 0 < len(uid) < UID_LEN
            continue
        assert len(uid) == UID_LEN
        assert 1 <= node_id <= MAX_NODE_ID and node_id != 1 and node_id not in heard - \
            {n for n, u in given_to.items() if u == uid}
        assert given_to.setdefault(node_id, uid) == uid, "one node ID for two unique IDs"
        assert alloc.table[uid] == node_id
