"""Fuzz targets for the MAVLink FTP server (``firmware.modules.mavlink.ftp``): random and
mutated request payloads, fed to the server alone (fast: many examples) and through a real
link of a booted FMU. The promises (docs/robustness.md): every request gets exactly one reply,
ACK or NAK with a valid ``MAV_FTP_ERR`` code, nothing outside the SD card is read or changed,
and the server keeps working (a listing afterwards is answered)."""

from __future__ import annotations

import os
import shutil
import struct
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mav

from firmware.modules.mavlink import ftp as srv
from tests.fuzzing import fuzz
from tests.mavlink.conftest import open_session
from tests.mavlink.ftp_client import ftp_call, parse

HDR = struct.Struct("<HBBBBBxI")
PATHS = [b"", b"/", b"/fs/microsd", b"/fs/microsd/log", b"log/2024-01-01/00_00_00.ulg",
         b"/fs/microsd/small.txt", b"small.txt", b"empty", b"new.bin", b"newdir", b"@MAV_LOG",
         b"@MAV_LOG/2024-01-01/00_00_00.ulg", b"@PARAM", b"@PARAM/param.pck",
         b"@PARAM/param.pck?withdefaults=1", b"@PARAM/other", b"../outside.txt",
         b"/../../outside.txt", b"link_out", b"/etc/passwd", b"\xff\xfe\x00", b"a\x00b",
         b"small.txt\x00moved.txt", b"x" * 239, b"/fs/microsd/" + "\u00e9".encode() * 50,
         b"/etc/extras", b"etc/extras/", b"/etc/extras/parameters.json",
         b"/etc/extras/component_general.json.xz", b"/etc/extras/nope.json",
         b"/etc/extras/../../outside.txt", b"etc/extrasx", b"/etc/extras/parameters.json\x00x"]
#: the component metadata folder's virtual files (what the link serves is built from the
#: parameter declarations; here any bytes do)
EXTRAS = {"component_general.json": b'{"version":1}', "component_general.json.xz": b"\xfd7z",
          "parameters.json": bytes(range(256)) * 3}
OPCODES = list(range(0, 17)) + [srv.OP_ACK, srv.OP_NAK, 200, 255]
OFFSETS = [0, 1, 5, 10, 239, 3000, srv.MAX_FILE_BYTES, srv.MAX_FILE_BYTES + 1, 0xFFFFFFFF]


@st.composite
def requests(draw: Any) -> bytes:
    """A request payload: structured (every field from interesting values or random), a
    structured one mutated (bits flipped, cut short), or random bytes."""
    kind = draw(st.sampled_from(["structured", "mutated", "random"]))
    if kind == "random":
        return draw(st.binary(min_size=0, max_size=251))
    data = draw(st.one_of(st.sampled_from(PATHS), st.binary(max_size=239)))
    size = draw(st.one_of(st.just(len(data)), st.integers(0, 255)))
    payload = bytearray(HDR.pack(draw(st.integers(0, 0xFFFF)),
                                 draw(st.sampled_from([0, 0, 0, 1, 255])),
                                 draw(st.sampled_from(OPCODES)), size,
                                 draw(st.integers(0, 255)), draw(st.integers(0, 1)),
                                 draw(st.one_of(st.sampled_from(OFFSETS),
                                                st.integers(0, 0xFFFFFFFF)))) + data)
    if kind == "mutated":
        for _ in range(draw(st.integers(1, 4))):
            pos = draw(st.integers(0, len(payload) - 1))
            payload[pos] ^= 1 << draw(st.integers(0, 7))
        payload = payload[:draw(st.integers(0, len(payload)))]
    return bytes(payload)


def _check_reply(req: bytes, reply: bytes) -> None:
    """One well-formed reply to ``req``: its sequence number + 1, its opcode, ACK or NAK, a
    NAK's data one valid code (two bytes exactly for FailErrno)."""
    full = req[:251].ljust(251, b"\x00")
    seq, _session, opcode = struct.unpack_from("<HBB", full)
    assert len(reply) == srv.PAYLOAD_LEN
    r_seq, _r_session, r_op, r_size, r_req_op = struct.unpack_from("<HBBBB", reply)
    assert r_seq == (seq + 1) & 0xFFFF and r_req_op == opcode
    assert r_op in (srv.OP_ACK, srv.OP_NAK) and r_size <= srv.MAX_DATA
    if r_op == srv.OP_NAK:
        code = reply[12]
        assert srv.ERR_FAIL <= code <= srv.ERR_NOT_FOUND, code
        assert r_size == (2 if code == srv.ERR_ERRNO else 1), (code, r_size)


def _seed(base: Path) -> Path:
    """A fresh SD card: a log, a small file, an empty folder, a link out; a file beside it."""
    sd = base / "sd"
    shutil.rmtree(sd, ignore_errors=True)
    (sd / "log" / "2024-01-01").mkdir(parents=True)
    (sd / "log" / "2024-01-01" / "00_00_00.ulg").write_bytes(bytes(range(256)) * 12)
    (sd / "small.txt").write_bytes(b"0123456789")
    (sd / "empty").mkdir()
    (base / "outside.txt").write_text("outside the card")
    (sd / "link_out").symlink_to(base / "outside.txt")
    return sd


def _outside(base: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in base.iterdir() if p.is_file()}


class _Params:
    """A two-parameter set in the shape of firmware.platform.params.Params."""

    class _Def:
        def __init__(self, t: str, default: float) -> None:
            self.type, self.default = t, default

    names = ["MAV_SYS_ID", "MPC_XY_VEL_MAX"]
    defs = {"MAV_SYS_ID": _Def("INT32", 1), "MPC_XY_VEL_MAX": _Def("FLOAT", 12.0)}
    values = {"MAV_SYS_ID": 1, "MPC_XY_VEL_MAX": 7.5}


@pytest.fixture(scope="module")
def sandbox(tmp_path_factory):
    return tmp_path_factory.mktemp("ftp_fuzz")


@fuzz(examples=180)
@given(reqs=st.lists(requests(), min_size=1, max_size=8))
def test_server_answers_every_request_once_and_stays_on_the_card(sandbox, reqs):
    sd = _seed(sandbox)
    before = _outside(sandbox)
    server = srv.FtpServer(sd, _Params(), lambda: EXTRAS)
    for i, req in enumerate(reqs):
        reply = server.handle(req, i * 1000)
        if reply is None:   # a burst started: its first packet is the reply
            full = req[:251].ljust(251, b"\x00")
            assert full[3] == srv.OP_BURST and server.streaming()
            packet = server.burst_packet()
            assert packet is not None
            _check_reply(req, packet)
            server.burst_sent(packet)
        else:
            _check_reply(req, reply)
    assert _outside(sandbox) == before
    assert sorted(p.name for p in sandbox.iterdir()) == ["outside.txt", "sd"]
    for root, _dirs, files in os.walk(sd):
        for f in files:
            p = Path(root) / f
            assert p.is_symlink() or p.stat().st_size <= srv.MAX_FILE_BYTES
    server.handle(HDR.pack(1, 0, srv.OP_RESET, 0, 0, 0, 0), 10**7)
    listing = server.handle(HDR.pack(3, 0, srv.OP_LIST, 1, 0, 0, 0) + b"/", 10**7)
    assert listing is not None and listing[3] in (srv.OP_ACK, srv.OP_NAK)
    if listing[3] == srv.OP_NAK:
        assert listing[12] == srv.ERR_EOF and not any(sd.iterdir())
    server.close()


# -- through a link -----------------------------------------------------------------------------

@pytest.fixture(scope="module")
def fmu(tmp_path_factory):
    s = open_session(tmp_path_factory.mktemp("fuzz_ftp"))
    s.gcs.wait_heartbeat()
    yield s
    s.close()


_SEQ = [10_000]


@fuzz(examples=45)
@given(reqs=st.lists(requests(), min_size=1, max_size=4))
def test_link_answers_every_ftp_request_once(fmu, reqs):
    gcs = fmu.gcs
    inst = fmu.udp_instance()
    errors, since_us = inst.rx_handler_errors, fmu.dmesg_mark()
    _seed(fmu.root)
    sent = []
    for req in reqs:
        _SEQ[0] = (_SEQ[0] + 1000) % 60_000
        full = bytearray(req[:251].ljust(251, b"\x00"))
        full[0:2] = struct.pack("<H", _SEQ[0])   # distinct, so each reply is identifiable
        mark = gcs.mark()
        gcs.send(mav.MAVLink_file_transfer_protocol_message(0, 1, 1, list(full)))
        gcs.step(0.03)
        replies = [parse(m) for m in gcs.messages("FILE_TRANSFER_PROTOCOL", mark)]
        mine = [r for r in replies if r["seq"] == (_SEQ[0] + 1) & 0xFFFF]
        assert len(mine) == 1, (full[:12].hex(), replies[:3])
        reply = mine[0]
        assert reply["req_opcode"] == full[3]
        assert reply["opcode"] in (srv.OP_ACK, srv.OP_NAK)
        if reply["opcode"] == srv.OP_NAK:
            assert srv.ERR_FAIL <= reply["data"][0] <= srv.ERR_NOT_FOUND
        sent.append(full)
    assert not fmu.orch.dead, f"the FMU died: {fmu.orch.dead}"
    assert fmu.mavlink_errors(since_us) == [] and inst.rx_handler_errors == errors
    assert (fmu.root / "outside.txt").read_text() == "outside the card"
    _SEQ[0] = (_SEQ[0] + 1000) % 60_000
    assert ftp_call(gcs, _SEQ[0], srv.OP_RESET)["opcode"] == srv.OP_ACK
    _SEQ[0] = (_SEQ[0] + 1000) % 60_000
    listing = ftp_call(gcs, _SEQ[0], srv.OP_LIST, b"/fs/microsd")
    assert listing["opcode"] == srv.OP_ACK and b"Dlog\x00" in listing["data"]
