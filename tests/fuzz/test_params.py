"""Fuzzing the parameter entry points: the FRAM store at boot, QGroundControl files (the
library function and the shell's ``param import``), the MAVLink parameter protocol and
``Params.set`` with any value.

The common invariant is that the store stays valid (every INT32 an int in the int32 range,
every FLOAT a finite float32) and that nothing already saved is lost; bad input is refused
with a ParamError or reported and skipped, never raised as anything else.
"""

from __future__ import annotations

import math
import struct
from types import SimpleNamespace

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mav

from board.kernel import Kernel
from firmware.modules.mavlink.params import ParamService
from firmware.platform import Platform
from firmware.platform.params import (
    INT32_MAX,
    INT32_MIN,
    MemoryPartition,
    ParamError,
    Params,
    ParamStorage,
    export_qgc,
    f32,
    import_qgc,
)
from tests.fuzz.test_bson import mutated_documents
from tests.fuzzing import fuzz
from tests.helpers import PARAM_DEFS as DEFS
from tests.helpers import terminates

NAMES = [d.name for d in DEFS]
NUMBERS = st.one_of(st.floats(), st.floats(width=32), st.integers(),
                    st.integers(INT32_MIN - 2, INT32_MAX + 2),
                    st.sampled_from([1e39, -1e39, 3.4028235e38, 3.5e38, 10 ** 400, -0.0,
                                     float("nan"), float("inf"), float("-inf")]))
ANYTHING = st.one_of(NUMBERS, st.booleans(), st.none(), st.text(max_size=8),
                     st.binary(max_size=8), st.lists(st.integers(), max_size=2))


def board():
    platform = Platform(Kernel("fuzz"))
    return platform


def assert_valid(params: Params) -> None:
    """Every stored value is one the real board could hold for its type."""
    for name in params.names:
        v = params.values[name]
        if params.defs[name].type == "INT32":
            assert type(v) is int and INT32_MIN <= v <= INT32_MAX, (name, v)
        else:
            assert type(v) is float and math.isfinite(v) and f32(v) == v, (name, v)


# -- Params.set ---------------------------------------------------------------------------------

@fuzz(examples=800)
@given(st.sampled_from(NAMES + ["NOPE", ""]), ANYTHING)
def test_set_accepts_a_valid_value_or_raises_param_error(name, value):
    """Invariant: Params.set returns the stored value or raises ParamError (nothing else);
    a refused value leaves the old one; the store stays valid."""
    p = Params(board(), DEFS)
    before = dict(p.values)
    try:
        stored = p.set(name, value)
    except ParamError:
        assert p.values == before
    else:
        assert p.values[name] == stored
    assert_valid(p)


# -- the FRAM store -----------------------------------------------------------------------------

def saved_store(platform, first: dict, second: dict) -> tuple[MemoryPartition, int]:
    """A partition holding two saves (``first`` then ``second``); returns it and the size of
    a slot."""
    part = MemoryPartition()
    p = Params(platform, DEFS, ParamStorage(part))
    for values in (first, second):
        for k, v in values.items():
            p.set(k, v, notify=False)
        assert p.save()
    return part, p.storage.slot_size


@st.composite
def damage(draw, size: int) -> list[tuple[int, bytes]]:
    """Writes confined to ``size`` bytes: bit flips, zeroed or erased runs, random bytes,
    hostile int32s (a header's sequence or length) or a bare PX4 document."""
    out = []
    for _ in range(draw(st.integers(1, 4))):
        how = draw(st.sampled_from(["flip", "zero", "erase", "random", "int32", "bson"]))
        at = draw(st.integers(0, size - 1))
        if how == "flip":
            out.append((at, None, draw(st.integers(0, 7))))
            continue
        n = draw(st.integers(1, 64))
        data = {"zero": b"\0" * n, "erase": b"\xff" * n,
                "random": draw(st.binary(min_size=1, max_size=64)),
                "int32": struct.pack("<I", draw(st.sampled_from(
                    [0, 1, 4, 5, 0x7FFFFFFF, 0x80000000, 0xFFFFFFFF, 0xFFFFFFFE, 4096]))),
                "bson": draw(mutated_documents())}[how]
        out.append((at, data[: size - at], 0))
    return out


def apply(part: MemoryPartition, base: int, writes) -> None:
    for at, data, bit in writes:
        if data is None:
            part.data[base + at] ^= 1 << bit
        else:
            part.data[base + at:base + at + len(data)] = data


@fuzz(examples=150)
@given(st.sampled_from([0, 1]), st.data())
def test_a_damaged_slot_never_loses_the_other_good_slot(slot, data):
    """Invariant: with one slot damaged in any way, boot loads the values saved in the slot
    it says it loaded: the newest save (slot 1) or, if that one is damaged, the one before
    it (slot 0), reported as a warning naming slot 1; never the defaults, never an
    exception, never a hang; the next save goes to the other slot, not over that copy."""
    platform = board()
    part, size = saved_store(platform, {"MC_ROLL_P": 5.0, "SYS_AUTOSTART": 4001},
                             {"MC_ROLL_P": 4.0})
    apply(part, slot * size, data.draw(damage(size)))
    p = Params(platform, DEFS, ParamStorage(part))
    with terminates():
        assert p.load()
    assert_valid(p)
    _t, level, _m, text = platform.dmesg[-1]
    loaded = p.storage.last_slot
    assert f"parameters loaded from slot {loaded} " in text, text
    saved = {0: (5.0, 4001), 1: (4.0, 4001)}[loaded]
    assert (p["MC_ROLL_P"], p["SYS_AUTOSTART"]) == saved
    if loaded == 0:  # the newest save (slot 1) was lost: said as a warning
        assert slot == 1 and level == 4 and "slot 1: " in text, text
    p.set("COM_RC_LOSS_T", 7.5, notify=False)
    assert p.save() and p.storage.last_slot == 1 - loaded  # never over the copy that loaded


@fuzz(examples=150)
@given(st.data())
def test_any_partition_image_boots_to_a_store_or_the_defaults(data):
    """Invariant: any partition image (random, or a good store damaged anywhere, both slots
    included) loads a valid store or the defaults, never raises, never hangs; a save after
    that is loaded back."""
    platform = board()
    if data.draw(st.booleans()):
        part = MemoryPartition(fill=data.draw(st.sampled_from([0x00, 0xFF, 0x55])))
        size = part.size
        apply(part, 0, data.draw(damage(size)))
    else:
        part, _ = saved_store(platform, {"MC_ROLL_P": 5.0}, {"MC_ROLL_P": 4.0})
        apply(part, 0, data.draw(damage(part.size)))
    p = Params(platform, DEFS, ParamStorage(part))
    with terminates():
        loaded = p.load()
    assert isinstance(loaded, bool)
    assert_valid(p)
    if not loaded:
        assert p.values == {d.name: d.default for d in DEFS}
    p.set("COM_RC_LOSS_T", 7.5, notify=False)
    assert p.save()
    q = Params(platform, DEFS, ParamStorage(part))
    assert q.load() and q.values == p.values


# -- QGroundControl files ---------------------------------------------------------------------

QGC_TOKENS = st.one_of(st.sampled_from(NAMES + ["1", "6", "9", "4", "nan", "inf", "-inf", "1e39",
                                                "-3.5e38", "0x10", "4001", "2.5", "#", "\t",
                                                "99999999999999999999", "1e-50"]),
                       st.text(max_size=6))


@st.composite
def qgc_texts(draw) -> str:
    """Random lines from QGC-like tokens, or a real export with lines mutated."""
    if draw(st.booleans()):
        lines = [draw(st.lists(QGC_TOKENS, max_size=7)) for _ in range(draw(st.integers(0, 8)))]
        return "\n".join("\t".join(line) for line in lines)
    p = Params(board(), DEFS)
    lines = export_qgc(p).splitlines()
    for _ in range(draw(st.integers(1, 4))):
        i = draw(st.integers(0, len(lines) - 1))
        fields = lines[i].split("\t")
        j = draw(st.integers(0, len(fields) - 1))
        fields[j] = draw(QGC_TOKENS)
        lines[i] = "\t".join(fields)
    return "\n".join(lines) + draw(st.sampled_from(["", "\n", "\r\n", "\x00"]))


@fuzz(examples=500)
@given(qgc_texts())
def test_qgc_import_reports_bad_lines_and_keeps_the_saved_store(text):
    """Invariant: import_qgc never raises; it counts what it set and reports every refused
    line with its number; the store stays valid; what was saved before is still loadable, and
    the autosave after the import holds the imported values."""
    platform = board()
    part = MemoryPartition()
    p = Params(platform, DEFS, ParamStorage(part))
    p.set("SYS_AUTOSTART", 4001)
    assert p.save()
    count, problems = import_qgc(p, text)
    assert count >= 0 and all(msg.startswith("line ") for msg in problems)
    assert_valid(p)
    platform.kernel.run(400_000_000)  # the autosave
    q = Params(platform, DEFS, ParamStorage(part))
    assert q.load() and q.values == p.values


@pytest.fixture(scope="module")
def sd(tmp_path_factory):
    return tmp_path_factory.mktemp("sd")


@fuzz(examples=400)
@given(qgc_texts(), st.binary(max_size=16))
def test_shell_param_import_never_fails_internally(sd, text, tail):
    """Invariant: `param import` of any file (text, or text with arbitrary bytes appended)
    exits 0 or 1 with its problems printed, never an internal error; the store stays valid."""
    from firmware.shell import Shell
    from firmware.system import System

    platform = board()
    p = Params(platform, DEFS)
    out: list[str] = []
    sh = Shell(System(platform, p, modules={}, sd_root=sd), out.append)
    (sd / "fuzz.params").write_bytes(text.encode("utf-8", "surrogatepass") + tail)
    status = sh.execute("param import fuzz.params")
    assert status in (0, 1) and "internal error" not in "".join(out), out
    assert_valid(p)


# -- the MAVLink parameter protocol -------------------------------------------------------------

class Link:
    """The parts of a MavlinkInstance the parameter service uses, recording what it sends."""

    def __init__(self, params: Params) -> None:
        self.system = SimpleNamespace(params=params)
        self.texts: list[str] = []
        self.values: list[bytes] = []

    def send_text(self, severity: int, text: str) -> None:
        self.texts.append(text)

    def send_packed(self, msg, crc_extra: int, payload: bytes, budget: bool = False) -> bool:
        self.values.append(payload)
        return True


_TX = mav.MAVLink(None, srcSystem=255)
_RX = mav.MAVLink(None)
_RX.robust_parsing = True

IDS = st.one_of(st.sampled_from(NAMES + ["_HASH_CHECK", "NOPE"]),
                st.binary(max_size=16).map(lambda b: b.decode("latin-1")))
RAW4 = st.one_of(st.binary(min_size=4, max_size=4),
                 st.sampled_from([struct.pack("<f", x) for x in (math.nan, math.inf, -math.inf,
                                                                 3.4e38, 1.0, -0.0)]),
                 st.integers(INT32_MIN, INT32_MAX).map(lambda i: struct.pack("<i", i)))
MESSAGES = st.one_of(
    st.tuples(st.just("set"), IDS, RAW4, st.integers(0, 255)),
    st.tuples(st.just("read"), IDS, st.integers(-32768, 32767)),
    st.tuples(st.just("list")),
)


def wire(request) -> object:
    """The request as the instance receives it: packed by a GCS and parsed off the wire."""
    if request[0] == "set":
        _, name, raw, ptype = request
        value = struct.unpack("<f", raw)[0]
        msg = mav.MAVLink_param_set_message(1, 1, name.encode("latin-1"), value, ptype)
    elif request[0] == "read":
        msg = mav.MAVLink_param_request_read_message(1, 1, request[1].encode("latin-1"),
                                                     request[2])
    else:
        msg = mav.MAVLink_param_request_list_message(1, 1)
    return _RX.decode(bytearray(msg.pack(_TX)))


@fuzz(examples=500)
@given(st.lists(MESSAGES, min_size=1, max_size=8))
def test_mavlink_parameter_protocol_never_raises(requests):
    """Invariant: any sequence of PARAM_SET / PARAM_REQUEST_READ / PARAM_REQUEST_LIST (random
    ids, types, NaN/inf/huge values) is handled without an exception; a set is answered with
    the parameter's current value; the store stays valid."""
    p = Params(board(), DEFS)
    link = Link(p)
    service = ParamService(link)
    handlers = service.handlers()
    for request in requests:
        m = wire(request)
        before = len(link.values)
        handlers[m.get_msgId()](m)
        service.update(0)
        assert_valid(p)
        if request[0] != "set":
            continue
        name = m.param_id if isinstance(m.param_id, str) else m.param_id.decode("latin-1")
        name = name.split("\x00", 1)[0]
        if name in p:
            answer = link.values[before]
            assert answer[8:8 + len(name)] == name.encode()[:16]
            want = struct.pack("<i" if p.defs[name].type == "INT32" else "<f", p.values[name])
            assert answer[:4] == want
