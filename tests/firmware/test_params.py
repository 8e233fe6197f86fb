"""Parameters: metadata, types, change notification, crash-safe storage, QGC files."""

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

DEFS = [
    ParamDef("SYS_AUTOSTART", "INT32", 0, group="System", short="Airframe",
             reboot_required=True),
    ParamDef("MC_ROLL_P", "FLOAT", 6.5, min=0.0, max=12.0, group="MC Attitude",
             short="Roll P gain", decimals=2),
    ParamDef("MC_PITCH_P", "FLOAT", 6.5, min=0.0, max=12.0, group="MC Attitude"),
    ParamDef("COM_RC_LOSS_T", "FLOAT", 0.5, unit="s", group="Commander"),
    ParamDef("COM_ARM_WO_GPS", "INT32", 1, values={0: "Deny", 1: "Allow"}, group="Commander"),
]


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
    values, _ = ParamStorage(part).load()
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


def test_real_px4_image_at_offset_zero_loads(platform):
    part = MemoryPartition()
    part.write(0, bson.encode({"SYS_AUTOSTART": 4001, "MC_ROLL_P": 6.5, "GONE_PARAM": 3}))
    p = make(platform, part)
    assert p.load()
    assert p["SYS_AUTOSTART"] == 4001
    assert any("unknown parameter GONE_PARAM" in line[3] for line in platform.dmesg)


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
    stream = [(off + i, b) for off, data in rec.writes for i, b in enumerate(data)]
    assert len(stream) > 30
    outcomes = set()
    for cut in range(len(stream) + 1):
        image = MemoryPartition()
        image.data[:] = before
        for addr, b in stream[:cut]:
            image.data[addr] = b
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
