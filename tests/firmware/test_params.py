"""Parameters: metadata, types, change notification, crash-safe storage, QGC files."""

import struct
import zlib

import pytest

from firmware.platform import bson
from firmware.platform.params import (
    MemoryPartition,
    ParamDef,
    ParamError,
    Params,
    ParamStorage,
    export_qgc,
    import_qgc,
    markdown_reference,
)
from firmware.platform.uorb import Subscription
from tests.helpers import PARAM_DEFS as DEFS
from tests.helpers import terminates


def make(platform, partition=None, **kw):
    storage = ParamStorage(partition) if partition is not None else None
    return Params(platform, DEFS, storage, **kw)


def test_px4_bson_example_from_the_reference():
    doc = bson.encode({"SYS_AUTOSTART": 4001, "MC_ROLL_P": 6.5})
    assert doc.hex(" ") == (
        "2b 00 00 00 10 53 59 53 5f 41 55 54 4f 53 54 41 52 54 00 a1 0f 00 00 01 4d 43 5f "
        "52 4f 4c 4c 5f 50 00 00 00 00 00 00 00 1a 40 00")
    assert bson.decode(doc) == {"SYS_AUTOSTART": 4001, "MC_ROLL_P": 6.5}


@pytest.mark.parametrize("data, message", [
    (b"\x00\x00\x00\x00\x00", "length field 0"),
    (b"\x10\x00\x00\x00\x10ABC", "length field 16 does not fit the 8 bytes"),
    (b"\x10\x00\x00\x00\x10ABCDEFGHIJK", "not terminated"),
    (b"\x0d\x00\x00\x00\x10A\x00\x01\x00\x00\x00\x00\xaa", "size 13 does not match 12"),
    (b"\x0a\x00\x00\x00\x77A\x00\x00\x00\x00", "unknown type 0x77"),
])
def test_bson_errors_say_what(data, message):
    with pytest.raises(bson.BsonError, match=message):
        bson.decode(data)


def test_erased_memory_is_no_data():
    assert bson.decode(b"\xff" * 64) is None


def test_types_and_float32_rounding(platform):
    p = make(platform)
    assert p["MC_ROLL_P"] == 6.5 and p["SYS_AUTOSTART"] == 0
    v = p.set("MC_ROLL_P", 0.1)
    assert v != 0.1 and abs(v - 0.1) < 1e-8  # stored as the STM32's float32
    with pytest.raises(ParamError, match="integer parameter"):
        p.set("SYS_AUTOSTART", 1.5)
    with pytest.raises(ParamError, match="unknown parameter"):
        p.set("NOPE", 1)
    with pytest.raises(ParamError, match="int32 range"):
        p.set("SYS_AUTOSTART", 1 << 40)
    assert p.index("COM_ARM_WO_GPS") == 0  # alphabetical, as PX4 indexes
    assert p.match("MC_") == ["MC_PITCH_P", "MC_ROLL_P"]


def test_set_publishes_parameter_update(platform, kernel):
    p = make(platform)
    sub = Subscription(platform.orb, "parameter_update")
    sub.copy()
    p.set("MC_ROLL_P", 7.0)
    msg = sub.update()
    assert msg is not None and msg.changed == 1
    p.set("MC_ROLL_P", 7.0)  # same value: no notification
    assert not sub.updated()


def test_save_and_load_round_trip_only_changed_values(platform):
    part = MemoryPartition()
    p = make(platform, part)
    p.set("SYS_AUTOSTART", 4001)
    p.set("MC_ROLL_P", 6.25)
    assert p.save()
    q = make(platform, part)
    assert q.load()
    assert q["SYS_AUTOSTART"] == 4001 and q["MC_ROLL_P"] == 6.25
    values, _, _ = ParamStorage(part).load()
    assert values == {"MC_ROLL_P": 6.25, "SYS_AUTOSTART": 4001}


def test_autosave_after_a_change(platform, kernel):
    part = MemoryPartition()
    p = make(platform, part)
    p.set("COM_RC_LOSS_T", 1.0)
    kernel.run(400_000_000)
    assert p.save_count == 1
    assert ParamStorage(part).load()[0] == {"COM_RC_LOSS_T": 1.0}


def test_erased_and_corrupt_stores_give_defaults_and_say_so(platform):
    p = make(platform, MemoryPartition())
    assert not p.load()
    assert "erased" in platform.dmesg[-1][3]
    junk = MemoryPartition(fill=0x00)
    junk.data[0:4] = b"\x00\x00\x00\x00"
    q = make(platform, junk)
    q.set("MC_ROLL_P", 3.0, notify=False)
    assert not q.load()
    assert q["MC_ROLL_P"] == 6.5
    assert "corrupt" in platform.dmesg[-1][3] and platform.dmesg[-1][1] == 3


def test_real_px4_image_is_not_read_at_boot_but_param_load_imports_it(platform, tmp_path):
    # A bare PX4 document carries no CRC: at boot it is reported, not trusted (the board's
    # store is two CRC-checked slots); `param load FILE` imports it on request.
    px4 = bson.encode({"SYS_AUTOSTART": 4001, "MC_ROLL_P": 6.25, "GONE_PARAM": 3})
    part = MemoryPartition()
    part.write(0, px4)
    p = make(platform, part)
    assert not p.load()
    assert p["SYS_AUTOSTART"] == 0
    _t, sev, _mod, text = platform.dmesg[-1]
    assert sev == 3 and "bare PX4 document" in text and "defaults loaded" in text
    from firmware.shell import Shell
    from firmware.system import System

    out = []
    sh = Shell(System(platform, p, modules={}, sd_root=tmp_path), out.append)
    (tmp_path / "px4.bson").write_bytes(px4 + b"\xff" * 100)  # a dump of the partition
    assert sh.execute("param load px4.bson") == 0
    assert p["SYS_AUTOSTART"] == 4001 and p["MC_ROLL_P"] == 6.25
    assert "loaded 2 parameters from px4.bson, 1 skipped" in "".join(out)
    assert any("unknown parameter GONE_PARAM" in line[3] for line in platform.dmesg)
    platform.kernel.run(400_000_000)  # the autosave
    assert make(platform, part).load()
    (tmp_path / "bad.bson").write_bytes(bytes.fromhex("0c000000 02 41 00 f9ffffff 00"))
    out.clear()
    assert sh.execute("param load bad.bson") == 1 and "nothing changed" in "".join(out)
    assert p["SYS_AUTOSTART"] == 4001


class Recorder:
    """A partition that records every byte written, to replay a save cut at any byte."""

    def __init__(self, base):
        self.base = base
        self.size = base.size
        self.writes = []

    def read(self, offset, n):
        return self.base.read(offset, n)

    def write(self, offset, data):
        self.writes.append((offset, bytes(data)))
        return self.base.write(offset, data)


def cut_images(before, writes):
    """(cut, image) for a power cut before each byte of ``writes`` (and after the last): the
    partition ``before`` with the first ``cut`` bytes written."""
    stream = [(off + i, b) for off, data in writes for i, b in enumerate(data)]
    assert len(stream) > 30
    for cut in range(len(stream) + 1):
        image = MemoryPartition()
        image.data[:] = before
        for addr, b in stream[:cut]:
            image.data[addr] = b
        yield cut, image


def test_power_cut_at_every_byte_of_a_save_keeps_old_or_new(platform):
    base = MemoryPartition()
    p = make(platform, base)
    p.set("MC_ROLL_P", 5.0, notify=False)
    assert p.save()
    p.set("MC_ROLL_P", 4.0, notify=False)
    assert p.save()  # two saves: both slots hold a copy
    before = bytes(base.data)
    rec = Recorder(MemoryPartition())
    rec.base.data[:] = before
    q = make(platform, rec)
    assert q.load() and q["MC_ROLL_P"] == 4.0
    q.set("MC_ROLL_P", 3.0, notify=False)
    assert q.save()
    outcomes = set()
    for cut, image in cut_images(before, rec.writes):
        r = make(platform, image)
        assert r.load(), f"store unreadable after a cut at byte {cut}"
        assert r["MC_ROLL_P"] in (4.0, 3.0), f"cut at byte {cut} gave {r['MC_ROLL_P']}"
        outcomes.add(r["MC_ROLL_P"])
    assert outcomes == {4.0, 3.0}


def test_qgc_export_import_round_trip_and_bad_lines(platform):
    p = make(platform)
    p.set("MC_ROLL_P", 0.123456789)
    p.set("SYS_AUTOSTART", 4001)
    text = export_qgc(p)
    assert "\tMC_ROLL_P\t" in text and text.count("\n") == 5 + len(DEFS)
    q = make(platform)
    n, problems = import_qgc(q, text)
    assert n == len(DEFS) and problems == []
    assert q.values == p.values
    bad = text + "garbage line\n1\t1\tNO_SUCH\t1\t6\n1\t1\tMC_PITCH_P\tabc\t9\n" \
                 "1\t1\tSYS_AUTOSTART\t2.5\t9\n1\t1\tCOM_RC_LOSS_T\t2.0\t9\n"
    r = make(platform)
    n, problems = import_qgc(r, bad)
    assert n == len(DEFS) + 1
    lines = text.count("\n")
    assert [msg.split(":")[0] for msg in problems] == [
        f"line {lines + 1}", f"line {lines + 2}", f"line {lines + 3}", f"line {lines + 4}"]
    assert r["COM_RC_LOSS_T"] == 2.0


def test_markdown_reference_lists_every_parameter():
    md = markdown_reference(DEFS)
    for d in DEFS:
        assert f"`{d.name}`" in md
    assert "## Commander" in md and "Reboot required" in md and "0: Deny" in md


def test_bad_declarations_rejected():
    with pytest.raises(ParamError):
        ParamDef("lower_case", "INT32", 0)
    with pytest.raises(ParamError):
        ParamDef("TOO_LONG_PARAMETER_NAME", "INT32", 0)
    with pytest.raises(ParamError):
        ParamDef("X", "STRING", 0)


# -- robustness (issue 18): reproducers of the defects fuzzing found -----------------------------

@pytest.mark.parametrize("data", [
    bytes.fromhex("0c000000 02 41 00 f9ffffff 00"),            # STRING, -7: looped for ever
    bytes.fromhex("0c000000 05 41 00 ecffffff 00"),            # BINDATA, -20: looped too
    bytes.fromhex("0c000000 02 41 00 18fcffff 00"),            # STRING, -1000: IndexError
    bytes.fromhex("11000000 02 41 00 ecffffff 00 00000000 00"),  # -20: read as {'A': ''}
    bytes.fromhex("10000000 05 41 00 ecffffff 00 000000 00"),  # BINDATA -20: {'A': b''}
    # a regression guard, not a reproducer: the old decoder refused this one too
    bytes.fromhex("0e000000 02 41 00 ffffff7f 00 00 00"),      # a length past the document
], ids=["string-loop", "bindata-loop", "index-error", "string-garbage", "bindata-garbage",
        "past-the-end-guard"])
def test_bson_negative_or_oversized_lengths_are_errors(data):
    with terminates(2.0):
        with pytest.raises(bson.BsonError):
            bson.decode(data)


def test_twelve_byte_image_no_longer_hangs_the_load(platform):
    part = MemoryPartition()
    part.write(0, bytes.fromhex("0c000000 02 41 00 f9ffffff 00"))
    p = make(platform, part)
    with terminates(2.0):
        assert not p.load()
    assert p.values == {d.name: d.default for d in DEFS}


@pytest.mark.parametrize("value", [1e39, -1e39, 3.5e38, 10 ** 400, float("nan"), float("inf")],
                         ids=["1e39", "-1e39", "3.5e38", "10**400", "nan", "inf"])
def test_values_beyond_float32_are_parameter_errors(platform, value):
    p = make(platform)
    with pytest.raises(ParamError, match="MC_ROLL_P"):
        p.set("MC_ROLL_P", value)
    assert p["MC_ROLL_P"] == 6.5
    assert p.set("MC_ROLL_P", 3.4028235e38) == 3.4028234663852886e38  # FLT_MAX itself is fine


def test_shell_param_set_beyond_float32_is_a_clear_error(platform, tmp_path):
    from firmware.shell import Shell
    from firmware.system import System

    out = []
    sh = Shell(System(platform, make(platform), modules={}, sd_root=tmp_path), out.append)
    assert sh.execute("param set MC_ROLL_P 1e39") == 1
    text = "".join(out)
    assert "internal error" not in text and "param set: MC_ROLL_P" in text and "float32" in text
    out.clear()
    assert sh.execute("param compare MC_ROLL_P -1e39") == 1 and "float32" in "".join(out)


def test_qgc_import_with_an_overflowing_value_applies_the_rest(platform):
    p = make(platform)
    sub = Subscription(platform.orb, "parameter_update")
    sub.copy()
    text = ("1\t1\tMC_ROLL_P\t1e39\t9\n1\t1\tSYS_AUTOSTART\t4001\t6\n"
            "1\t1\tMC_PITCH_P\t-3e38\t9\n1\t1\tCOM_RC_LOSS_T\t2.5\t9\n")
    n, problems = import_qgc(p, text)
    assert n == 3 and p["SYS_AUTOSTART"] == 4001 and p["COM_RC_LOSS_T"] == 2.5
    assert p["MC_ROLL_P"] == 6.5 and len(problems) == 1 and problems[0].startswith("line 1:")
    assert sub.update() is not None  # what was applied is announced (and autosaved)


def _slot_image(values_doc, seq=1, slot=0, part=None):
    """A partition (``part`` or a new one) whose ``slot`` holds ``values_doc`` (raw BSON
    bytes) under a valid header: the CRC checks out whatever the document says."""
    part = MemoryPartition() if part is None else part
    base = slot * (part.size // 2)
    body = struct.pack("<II", seq, len(values_doc)) + values_doc
    part.write(base + 16, values_doc)
    part.write(base, struct.pack("<4sIII", b"PRM1", seq, len(values_doc), zlib.crc32(body)))
    return part


def test_boot_load_skips_an_overflowing_value_and_loads_the_rest(platform):
    doc = bson.encode({"MC_ROLL_P": 1e39, "SYS_AUTOSTART": 4001, "COM_RC_LOSS_T": 2.5})
    p = make(platform, _slot_image(doc))
    assert p.load()
    assert p["SYS_AUTOSTART"] == 4001 and p["COM_RC_LOSS_T"] == 2.5 and p["MC_ROLL_P"] == 6.5
    warns = [m for _t, sev, mod, m in platform.dmesg if sev == 4 and mod == "param"]
    assert any("MC_ROLL_P" in m and "float32" in m for m in warns), platform.dmesg


def test_save_sequence_wraps_at_two_to_the_32(platform):
    part = MemoryPartition()
    p = make(platform, part)
    p.storage.sequence = 0xFFFFFFFE
    p.set("MC_ROLL_P", 1.0, notify=False)
    assert p.save()  # save #0xFFFFFFFF
    p.set("MC_ROLL_P", 2.0, notify=False)
    assert p.save()  # the next one wraps to #0
    assert p.storage.sequence == 0
    q = make(platform, part)
    assert q.load() and q["MC_ROLL_P"] == 2.0  # the wrapped save is the newest
    assert q.storage.sequence == 0
    q.set("MC_ROLL_P", 3.0, notify=False)
    assert q.save() and q.storage.sequence == 1
    r = make(platform, part)
    assert r.load() and r["MC_ROLL_P"] == 3.0


def test_falling_back_to_the_older_slot_is_a_warning(platform):
    part = MemoryPartition()
    p = make(platform, part)
    p.set("MC_ROLL_P", 5.0, notify=False)
    assert p.save()  # slot 0, save #1
    p.set("MC_ROLL_P", 4.0, notify=False)
    assert p.save()  # slot 1, save #2
    part.data[p.storage.slot_size + 20] ^= 0x40  # the newest copy is damaged
    q = make(platform, part)
    assert q.load() and q["MC_ROLL_P"] == 5.0
    t, sev, mod, text = platform.dmesg[-1]
    assert sev == 4 and "slot 1" in text and "slot 0" in text and "CRC" in text, text


def test_a_save_after_falling_back_never_overwrites_the_only_good_copy(platform):
    # Slot 1 is the newest save and its CRC checks out, but its document does not decode (the
    # twelve bytes that used to hang the decoder): the load falls back to slot 0. The next
    # save must go to slot 1, the damaged one: it used to go to slot 0, so a power cut during
    # it lost every parameter.
    good = bson.encode({"MC_ROLL_P": 5.0, "SYS_AUTOSTART": 4001})
    part = _slot_image(good, seq=7, slot=0)
    _slot_image(bytes.fromhex("0c000000 02 41 00 f9ffffff 00"), seq=8, slot=1, part=part)
    before = bytes(part.data)
    rec = Recorder(MemoryPartition())
    rec.base.data[:] = before
    q = make(platform, rec)
    assert q.load() and q["MC_ROLL_P"] == 5.0
    assert "slot 1: save #8 does not decode" in platform.dmesg[-1][3]
    q.set("COM_RC_LOSS_T", 2.0, notify=False)
    assert q.save()
    assert q.storage.last_slot == 1 and q.storage.sequence == 9  # newer than both
    outcomes = set()
    for cut, image in cut_images(before, rec.writes):
        r = make(platform, image)
        assert r.load(), f"store unreadable after a cut at byte {cut}"
        assert (r["MC_ROLL_P"], r["SYS_AUTOSTART"]) == (5.0, 4001), f"cut at byte {cut}"
        outcomes.add(r["COM_RC_LOSS_T"])
    assert outcomes == {0.5, 2.0}  # the old copy, then (the save complete) the new one
