"""MAVLink FTP with pymavlink's own client (``pymavlink.mavftp.MAVFTP``) against the FMU's
UDP link: the log folder listed and read byte for byte, ``@PARAM/param.pck`` decoded to what
PARAM_REQUEST_LIST gives, a file written, read back, checked by CRC and removed; and bad
requests answered with the right NAK (raw FILE_TRANSFER_PROTOCOL, as a broken client sends)."""

from __future__ import annotations

import struct
import zlib

import pytest
from pymavlink import mavftp
from pymavlink.dialects.v20 import common as mav

from firmware.modules.mavlink import ftp as srv
from tests.mavlink.ftp_client import ftp_call, ftp_client


@pytest.fixture
def client(session, monkeypatch):
    return ftp_client(session, monkeypatch)


@pytest.fixture(scope="module")
def logs(session):
    """A real ULog from the logger and a file of an awkward size (not a multiple of 239)."""
    session.shell("param set SDLOG_MODE 1")
    session.orch.call("fmu", "shell", "logger stop")
    session.shell("logger start")
    session.gcs.step(0.5)
    session.shell("logger stop")
    root = session.root / "sd" / "log"
    extra = root / "2024-05-06" / "07_08_09.ulg"
    extra.parent.mkdir(parents=True, exist_ok=True)
    extra.write_bytes(bytes(range(256)) * 300 + b"tail")
    return sorted(root.rglob("*.ulg"))


def test_autopilot_version_advertises_ftp(session):
    gcs = session.gcs
    mark = gcs.mark()
    gcs.command_long(mav.MAV_CMD_REQUEST_MESSAGE, [mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION])
    m = gcs.wait_message("AUTOPILOT_VERSION", since=mark)
    assert m.capabilities & mav.MAV_PROTOCOL_CAPABILITY_FTP


@pytest.mark.parametrize("log_root", ["/fs/microsd/log", "@MAV_LOG"])
def test_log_folder_lists_and_reads_byte_identical(session, client, logs, log_root):
    ret = client.cmd_list([log_root])
    assert ret.error_code == mavftp.FtpError.Success
    days = sorted(e.name for e in ret.directory_listing if e.is_dir)
    assert days == sorted({p.parent.name for p in logs})
    listed = {}
    for day in days:
        ret = client.cmd_list([f"{log_root}/{day}"])
        assert ret.error_code == mavftp.FtpError.Success
        listed.update({f"{day}/{e.name}": e.size_b for e in ret.directory_listing})
    assert listed == {f"{p.parent.name}/{p.name}": p.stat().st_size for p in logs}
    for p in logs:
        data = client.read(f"{log_root}/{p.parent.name}/{p.name}", p.stat().st_size)
        assert data == p.read_bytes(), p
    assert session.udp_instance().ftp.server.session is None  # the client closed it


def test_param_pck_decodes_to_the_parameter_list(session, client):
    session.shell("param set MPC_XY_VEL_MAX 7.5")
    session.shell("param set COM_DISARM_LAND 4")
    gcs = session.gcs
    listed = gcs.param_list()
    data = client.read("@PARAM/param.pck", 1 << 20)
    pdata = mavftp.MAVFTP.ftp_param_decode(data)
    assert pdata is not None
    got = {name.decode(): value for name, value, _ in pdata.params}
    assert list(got) == sorted(listed)       # index order, every parameter once
    for name, value in listed.items():
        assert got[name] == pytest.approx(value, rel=1e-7, abs=0), name
    assert isinstance(got["COM_DISARM_LAND"], float) and got["COM_DISARM_LAND"] == 4.0
    types = {name.decode(): ptype for name, _, ptype in pdata.params}
    assert types["MAV_SYS_ID"] == srv.PCK_INT32 and types["MPC_XY_VEL_MAX"] == srv.PCK_FLOAT

    data = client.read("@PARAM/param.pck?withdefaults=1", 1 << 20)
    pdata = mavftp.MAVFTP.ftp_param_decode(data)
    defaults = {name.decode(): value for name, value, _ in pdata.defaults}
    params = session.orch.handles["fmu"].endpoint.board.system.params
    assert defaults["MPC_XY_VEL_MAX"] == pytest.approx(params.defs["MPC_XY_VEL_MAX"].default)
    assert defaults["MAV_SYS_ID"] == 1


def test_write_read_back_crc_rename_and_remove(session, client, tmp_path):
    sd = session.root / "sd"
    local = tmp_path / "up.bin"
    body = bytes((i * 7 + 3) & 0xFF for i in range(5_000)) + b"odd"
    local.write_bytes(body)
    assert client.cmd_mkdir(["/fs/microsd/ftptest"]).error_code == mavftp.FtpError.Success
    assert (sd / "ftptest").is_dir()
    client.cmd_put([str(local), "/fs/microsd/ftptest/up.bin"])
    assert client.process_ftp_reply("put", timeout=30).error_code == mavftp.FtpError.Success
    assert (sd / "ftptest" / "up.bin").read_bytes() == body
    assert client.read("/fs/microsd/ftptest/up.bin", len(body)) == body

    mark = session.gcs.mark()
    assert client.cmd_crc(["/fs/microsd/ftptest/up.bin"]).error_code == mavftp.FtpError.Success
    ack = next(m for m in session.gcs.messages("FILE_TRANSFER_PROTOCOL", mark)
               if m.payload[5] == srv.OP_CRC32)
    crc = struct.unpack("<I", bytes(ack.payload[12:16]))[0]
    # PX4's crc32part: zlib's CRC-32 without its initial and final inversion
    assert crc == zlib.crc32(body, 0xFFFFFFFF) ^ 0xFFFFFFFF == srv.crc32_px4(body)

    assert client.cmd_rename(["/fs/microsd/ftptest/up.bin",
                              "/fs/microsd/ftptest/moved.bin"]).error_code == 0
    assert (sd / "ftptest" / "moved.bin").read_bytes() == body
    assert client.cmd_rmdir(["/fs/microsd/ftptest"]).error_code == mavftp.FtpError.FailErrno
    assert client.cmd_rm(["/fs/microsd/ftptest/moved.bin"]).error_code == 0
    assert client.cmd_rmdir(["/fs/microsd/ftptest"]).error_code == 0
    assert not (sd / "ftptest").exists()
    ret = client.cmd_rm(["/fs/microsd/ftptest/moved.bin"])
    assert ret.error_code == mavftp.FtpError.FileNotFound


# -- bad requests, raw -------------------------------------------------------------------------

def _nak(reply: dict, code: int, err: int | None = None) -> None:
    assert reply["opcode"] == srv.OP_NAK, reply
    assert reply["data"][0] == code, reply
    if err is not None:
        assert reply["data"] == bytes((srv.ERR_ERRNO, err)), reply
    else:
        assert reply["size"] == 1


def test_bad_requests_get_the_right_nak(session):
    gcs = session.gcs
    sd = session.root / "sd"
    (session.root / "secret.txt").write_text("outside the card")
    (sd / "link_out").unlink(missing_ok=True)
    (sd / "link_out").symlink_to(session.root / "secret.txt")
    (sd / "small.txt").write_bytes(b"0123456789")
    seq = 1000
    assert ftp_call(gcs, seq, srv.OP_RESET)["opcode"] == srv.OP_ACK
    _nak(ftp_call(gcs, seq + 2, srv.OP_LIST, b"/", size=240), srv.ERR_DATA_SIZE)
    _nak(ftp_call(gcs, seq + 4, 99), srv.ERR_UNKNOWN)
    _nak(ftp_call(gcs, seq + 6, srv.OP_READ, session=0), srv.ERR_SESSION)
    _nak(ftp_call(gcs, seq + 8, srv.OP_OPEN_RO, b"/fs/microsd/nope.bin"), srv.ERR_NOT_FOUND)
    _nak(ftp_call(gcs, seq + 10, srv.OP_OPEN_RO, b"../secret.txt"), srv.ERR_NOT_FOUND)
    _nak(ftp_call(gcs, seq + 12, srv.OP_OPEN_RO, b"/../../secret.txt"), srv.ERR_NOT_FOUND)
    _nak(ftp_call(gcs, seq + 14, srv.OP_OPEN_RO, b"link_out"), srv.ERR_ERRNO, srv.NUTTX_EACCES)
    _nak(ftp_call(gcs, seq + 16, srv.OP_OPEN_RO, b"/fs/microsd/\xff\xfe"), srv.ERR_ERRNO,
         srv.NUTTX_EINVAL)
    _nak(ftp_call(gcs, seq + 18, srv.OP_LIST, b"/fs/microsd/small.txt"), srv.ERR_NOT_FOUND)
    _nak(ftp_call(gcs, seq + 20, srv.OP_REMOVE_FILE, b"@PARAM/param.pck"), srv.ERR_PROTECTED)
    _nak(ftp_call(gcs, seq + 22, srv.OP_CREATE, b"@PARAM/param.pck"), srv.ERR_PROTECTED)
    _nak(ftp_call(gcs, seq + 24, srv.OP_RMDIR, b"/fs/microsd"), srv.ERR_PROTECTED)
    _nak(ftp_call(gcs, seq + 26, srv.OP_MKDIR, b"log"), srv.ERR_EXISTS)

    opened = ftp_call(gcs, seq + 28, srv.OP_OPEN_RO, b"/fs/microsd/small.txt")
    assert opened["opcode"] == srv.OP_ACK and opened["data"] == struct.pack("<I", 10)
    _nak(ftp_call(gcs, seq + 30, srv.OP_OPEN_RO, b"small.txt"), srv.ERR_NO_SESSIONS)
    _nak(ftp_call(gcs, seq + 32, srv.OP_READ, session=3), srv.ERR_SESSION)
    read = ftp_call(gcs, seq + 34, srv.OP_READ, session=0, offset=4, size=100)
    assert read["opcode"] == srv.OP_ACK and read["data"] == b"456789"
    _nak(ftp_call(gcs, seq + 36, srv.OP_READ, session=0, offset=10), srv.ERR_EOF)
    _nak(ftp_call(gcs, seq + 38, srv.OP_READ, session=0, offset=0xFFFFFFFF), srv.ERR_EOF)
    _nak(ftp_call(gcs, seq + 40, srv.OP_WRITE, b"x", session=0), srv.ERR_ERRNO, srv.NUTTX_EBADF)
    mark = gcs.mark()
    gcs_seq = seq + 42
    burst = ftp_call(gcs, gcs_seq, srv.OP_BURST, session=0, offset=8)
    assert burst["opcode"] == srv.OP_ACK and burst["data"] == b"89"
    gcs.step(0.05)
    eof = [m for m in gcs.messages("FILE_TRANSFER_PROTOCOL", mark)
           if m.payload[0] | m.payload[1] << 8 == gcs_seq + 2]
    assert len(eof) == 1 and eof[0].payload[3] == srv.OP_NAK and eof[0].payload[12] == srv.ERR_EOF
    assert ftp_call(gcs, seq + 44, srv.OP_TERMINATE, session=0)["opcode"] == srv.OP_ACK
    _nak(ftp_call(gcs, seq + 46, srv.OP_TERMINATE, session=0), srv.ERR_SESSION)
    # nothing outside the card was touched, and the server still lists
    assert (session.root / "secret.txt").read_text() == "outside the card"
    listing = ftp_call(gcs, seq + 48, srv.OP_LIST, b"/fs/microsd")
    assert listing["opcode"] == srv.OP_ACK and b"Fsmall.txt\t10\x00" in listing["data"]
    assert session.udp_instance().rx_handler_errors == 0


def test_a_repeated_request_gets_the_same_reply_without_running_twice(session):
    """PX4 answers a request with the sequence number of the last one with the last reply
    (the GCS resent it because the reply was lost): a repeated CreateDirectory is not
    FileExists, a repeated RemoveFile not FileNotFound."""
    gcs = session.gcs
    first = ftp_call(gcs, 2000, srv.OP_MKDIR, b"/fs/microsd/again")
    again = ftp_call(gcs, 2000, srv.OP_MKDIR, b"/fs/microsd/again")
    assert first["opcode"] == again["opcode"] == srv.OP_ACK
    _nak(ftp_call(gcs, 2002, srv.OP_MKDIR, b"/fs/microsd/again"), srv.ERR_EXISTS)
    assert ftp_call(gcs, 2004, srv.OP_RMDIR, b"/fs/microsd/again")["opcode"] == srv.OP_ACK


# -- the server alone ---------------------------------------------------------------------------

def test_an_idle_session_is_closed_after_10_s_as_px4_does(tmp_path):
    (tmp_path / "f.bin").write_bytes(b"abc")
    server = srv.FtpServer(tmp_path, None)
    opened = server.handle(srv.HEADER.pack(1, 0, srv.OP_OPEN_RO, 5, 0, 0, 0) + b"f.bin", 0)
    assert opened is not None and opened[3] == srv.OP_ACK
    server.idle(srv.SESSION_TIMEOUT_US)
    assert server.session is not None           # 10 s exactly: still open
    server.idle(srv.SESSION_TIMEOUT_US + 1)
    assert server.session is None
    reread = server.handle(srv.HEADER.pack(3, 0, srv.OP_READ, 0, 0, 0, 0), 11_000_000)
    assert reread is not None and reread[3] == srv.OP_NAK and reread[12] == srv.ERR_SESSION


def test_param_pck_shares_long_prefixes_within_the_format_s_4_bits():
    """Names sharing 15 characters or more (the prefix field's limit), and a name that is the
    next one's prefix, still decode."""

    class _Def:
        def __init__(self, t: str, default: float) -> None:
            self.type, self.default = t, default

    class _Params:
        names = ["ABCDEFGHIJKLMNO", "ABCDEFGHIJKLMNOP", "ABCDEFGHIJKLMNOQ", "B"]
        defs = {n: _Def("INT32" if n != "B" else "FLOAT", 0) for n in names}
        values = {n: i for i, n in enumerate(names)}

    pdata = mavftp.MAVFTP.ftp_param_decode(srv.pack_params(_Params(), False))
    assert pdata is not None
    assert [(n.decode(), v) for n, v, _ in pdata.params] == \
        [(n, float(i) if n == "B" else i) for i, n in enumerate(_Params.names)]
