"""Fuzzing the BSON decoder that reads the parameter documents from FRAM and `param load`.

The decoder takes bytes nobody vouches for (a damaged FRAM, a file on the SD card), so every
input either decodes or raises the one documented error, ``bson.BsonError``, and decoding
always ends. Inputs are random bytes and mutations of valid documents (bit flips, truncations,
splices, length fields overwritten with hostile values), so the fuzzer reaches the elements'
own lengths and not only the document header.
"""

from __future__ import annotations

import math
import struct

from hypothesis import given
from hypothesis import strategies as st

from firmware.platform import bson
from tests.fuzzing import fuzz
from tests.helpers import terminates

NAMES = st.text(alphabet="ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_", min_size=1, max_size=16)
VALUES = st.one_of(st.integers(-(1 << 31), (1 << 31) - 1),
                   st.floats(allow_nan=False, width=64))
DOCS = st.dictionaries(NAMES, VALUES, max_size=12)
#: int32 values that hurt a length field: negative, zero, one past, huge
HOSTILE_I32 = st.sampled_from([-1, -4, -5, -7, -20, -1000, -(1 << 31), 0, 1, 3, 4, 5, 0x7FFFFFFF,
                               0x10000, 255])


def check_decode(data: bytes) -> None:
    with terminates():
        try:
            out = bson.decode(data)
        except bson.BsonError:
            return
    if out is None:
        return
    assert isinstance(out, dict)
    for name, value in out.items():
        assert isinstance(name, str) and len(name) < bson.MAX_NAME
        assert isinstance(value, (int, float, bool, str, bytes))
        if isinstance(value, (str, bytes)):
            assert len(value) <= len(data)


@st.composite
def mutated_documents(draw) -> bytes:
    """A valid document (with the STRING and BINDATA elements PX4 also decodes), then one to
    four mutations."""
    doc = bytearray(bson.encode(draw(DOCS)))
    extra = draw(st.lists(st.tuples(st.sampled_from([bson.STRING, bson.BINDATA]), NAMES,
                                    st.binary(max_size=12)), max_size=2))
    for kind, name, payload in extra:  # append real STRING/BINDATA elements before the end
        raw = name.encode()
        if kind == bson.STRING:
            elem = bytes((kind,)) + raw + b"\0" + struct.pack("<i", len(payload) + 1) + payload \
                + b"\0"
        else:
            elem = bytes((kind,)) + raw + b"\0" + struct.pack("<i", len(payload)) + b"\0" + payload
        doc[-1:-1] = elem
        doc[0:4] = struct.pack("<i", len(doc))
    for _ in range(draw(st.integers(1, 4))):
        how = draw(st.sampled_from(["flip", "truncate", "splice", "int32", "byte", "extend"]))
        if how == "flip" and doc:
            i = draw(st.integers(0, len(doc) * 8 - 1))
            doc[i // 8] ^= 1 << (i % 8)
        elif how == "truncate":
            del doc[draw(st.integers(0, len(doc))):]
        elif how == "splice":
            other = bson.encode(draw(DOCS))
            a = draw(st.integers(0, len(doc)))
            b = draw(st.integers(0, len(other)))
            doc[a:] = other[b:]
        elif how == "int32" and len(doc) >= 4:
            at = draw(st.integers(0, len(doc) - 4))
            doc[at:at + 4] = struct.pack("<i", draw(HOSTILE_I32))
        elif how == "byte" and doc:
            doc[draw(st.integers(0, len(doc) - 1))] = draw(st.sampled_from(
                [0x00, 0x01, 0x02, 0x05, 0x08, 0x10, 0x12, 0xFF, 0x77]))
        elif how == "extend":
            doc += draw(st.binary(max_size=16))
    return bytes(doc)


@fuzz(examples=1500)
@given(st.binary(max_size=96))
def test_random_bytes_decode_or_raise_bson_error(data):
    """Invariant: any bytes decode to a dict (or None for erased memory) or raise BsonError,
    never another exception; decoding terminates."""
    check_decode(data)


@fuzz(examples=400)
@given(mutated_documents())
def test_mutated_documents_decode_or_raise_bson_error(data):
    """Invariant: a valid document after bit flips, truncation, splices and hostile length
    fields decodes or raises BsonError, never another exception; decoding terminates; decoded
    strings and blobs are never longer than the input."""
    check_decode(data)


@fuzz(examples=500)
@given(DOCS)
def test_valid_documents_round_trip(values):
    """Invariant: what the encoder writes the decoder reads back unchanged (the float bits
    too), and the length field is the document's size."""
    doc = bson.encode(values)
    assert struct.unpack_from("<i", doc)[0] == len(doc)
    back = bson.decode(doc)
    assert back == values
    for name, v in values.items():
        assert type(back[name]) is type(v)
        if isinstance(v, float):
            assert math.copysign(1.0, back[name]) == math.copysign(1.0, v)
