"""MAVLink FTP: the file server of one link (FILE_TRANSFER_PROTOCOL, message #110).

As PX4's ``MavlinkFTP`` (src/modules/mavlink/mavlink_ftp.cpp) on the FMUv2, following the
protocol at https://mavlink.io/en/services/ftp.html:

* every request is a 12-byte header (``seq`` u16, ``session``, ``opcode``, ``size``,
  ``req_opcode``, ``burst_complete``, padding, ``offset`` u32) and up to 239 data bytes; the
  reply is the same header with ``opcode`` ACK (128) or NAK (129), ``req_opcode`` the request's
  opcode, ``seq`` the request's + 1 and the offset echoed. A NAK's data is the error code
  (``MAV_FTP_ERR``), and for ``FailErrno`` the errno as NuttX numbers it;
* one session (id 0), as PX4 has: an open while it is open is ``NoSessionsAvailable``; a
  request naming another session, or none open, ``InvalidSession``; a session without a
  request for 10 s is closed (PX4's ``send()``);
* a request repeated with the same sequence number (its reply was lost) gets the same reply
  again without being run twice, for replies of at most 4 data bytes (PX4 keeps only those);
  the emulator also requires the same opcode and session, so a stray request cannot be
  answered with another's reply;
* BurstReadFile streams the file from the offset as the link's data rate allows (PX4 sends
  while its TX buffer has room): ACKs with consecutive sequence numbers, ``burst_complete`` on
  the packet after more than 35,000 bytes of one burst (PX4's figure), a NAK ``EOF`` at the
  end of the file;
* CalcFileCRC32 is PX4's ``crc32part`` from 0 (the reflected CRC-32 without zlib's initial
  and final inversion: ``crc32_px4(d) == zlib.crc32(d, 0xFFFFFFFF) ^ 0xFFFFFFFF``).

What it serves, and how paths map (the emulator's choices are marked):

* the SD card. PX4's root on NuttX is ``/`` and clients name ``/fs/microsd/...``; here that
  prefix is the SD card's root, and so is any other path (``/log``, ``log``): the SD card is
  the only file system served (the ROMFS and ``/dev`` are not). ``..`` stops at the root
  (POSIX's ``/..``), and a symbolic link leading outside is refused (``FailErrno`` EACCES),
  so no request reaches a host file outside the card;
* ``@MAV_LOG``: the log folder (``/fs/microsd/log``), the MAVLink FTP alias for log
  download that QGroundControl and MAVSDK ask for first (PX4 >= 1.17, ArduPilot);
* ``@PARAM/param.pck`` (``?withdefaults=1``): every parameter in ArduPilot's packed format
  (AP_Filesystem_Param), which ground stations download instead of PARAM_REQUEST_LIST where a
  vehicle offers it (PX4 has no such file; the emulator serves it because the format is what
  QGroundControl, Mission Planner and pymavlink's ``getparams`` read). Read only;
* ``/etc/extras``: the component metadata files COMPONENT_METADATA names (general and
  parameter metadata, plain and xz; :mod:`firmware.modules.mavlink.component_metadata`), a
  read-only virtual folder as PX4's ROMFS ``/etc/extras``.

Bad input always gets exactly one reply: a ``size`` above 239 is ``InvalidDataSize``; an
unknown opcode ``UnknownCommand``; a path that is not UTF-8 ``FailErrno`` EINVAL (the
emulator's choice); a read at or past the end ``EOF``; a missing file or directory
``FileNotFound``; an existing one for CreateDirectory ``FileExists``; a change to a virtual
file or to the card's root ``FileProtected``; a write or truncate that would make a file
larger than :data:`MAX_FILE_BYTES` ``FailErrno`` EFBIG (the emulator's bound, so that one
request cannot fill the host's disk).
"""

from __future__ import annotations

import errno
import os
import posixpath
import struct
import zlib
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

from firmware.modules.mavlink.dialect import mav
from firmware.modules.mavlink.param_pack import PCK_FLOAT, PCK_INT32, pack_params

if TYPE_CHECKING:
    from firmware.modules.mavlink.instance import MavlinkInstance

__all__ = ["MAX_DATA", "MAX_FILE_BYTES", "PAYLOAD_LEN", "FtpServer", "FtpService", "crc32_px4",
           "pack_params"]

HEADER: Final = struct.Struct("<HBBBBBxI")
HDR_LEN: Final = 12
PAYLOAD_LEN: Final = 251
MAX_DATA: Final = PAYLOAD_LEN - HDR_LEN
#: the emulator's bound on a file grown over FTP (write or truncate)
MAX_FILE_BYTES: Final = 1 << 25
#: PX4: a burst ends (burst_complete) after this many bytes, the client asks for the next
BURST_CHUNK_BYTES: Final = 35_000
#: PX4: a session without a request for this long is closed
SESSION_TIMEOUT_US: Final = 10_000_000

# opcodes (MAV_FTP_OPCODE)
OP_NONE: Final = 0
OP_TERMINATE: Final = 1
OP_RESET: Final = 2
OP_LIST: Final = 3
OP_OPEN_RO: Final = 4
OP_READ: Final = 5
OP_CREATE: Final = 6
OP_WRITE: Final = 7
OP_REMOVE_FILE: Final = 8
OP_MKDIR: Final = 9
OP_RMDIR: Final = 10
OP_OPEN_WO: Final = 11
OP_TRUNCATE: Final = 12
OP_RENAME: Final = 13
OP_CRC32: Final = 14
OP_BURST: Final = 15
OP_ACK: Final = 128
OP_NAK: Final = 129

# error codes (MAV_FTP_ERR)
ERR_FAIL: Final = 1
ERR_ERRNO: Final = 2
ERR_DATA_SIZE: Final = 3
ERR_SESSION: Final = 4
ERR_NO_SESSIONS: Final = 5
ERR_EOF: Final = 6
ERR_UNKNOWN: Final = 7
ERR_EXISTS: Final = 8
ERR_PROTECTED: Final = 9
ERR_NOT_FOUND: Final = 10

#: host errno -> NuttX errno (the numbers the FMU would send; the same as Linux's for these)
_NUTTX_ERRNO: Final[dict[int, int]] = {
    errno.EPERM: 1, errno.ENOENT: 2, errno.EIO: 5, errno.EBADF: 9, errno.EACCES: 13,
    errno.EBUSY: 16, errno.EEXIST: 17, errno.EXDEV: 18, errno.ENOTDIR: 20, errno.EISDIR: 21,
    errno.EINVAL: 22, errno.EFBIG: 27, errno.ENOSPC: 28, errno.EROFS: 30,
    errno.ENAMETOOLONG: 36, errno.ENOTEMPTY: 39,
}
NUTTX_EINVAL: Final = 22
NUTTX_EACCES: Final = 13
NUTTX_EBADF: Final = 9
NUTTX_EISDIR: Final = 21
NUTTX_EFBIG: Final = 27

SD_PREFIX: Final = "/fs/microsd"
LOG_ALIAS: Final = "@MAV_LOG"
PARAM_DIR: Final = "@PARAM"
PARAM_FILE: Final = "param.pck"
EXTRAS_DIR: Final = "etc/extras"
def crc32_px4(data: bytes, crc: int = 0) -> int:
    """PX4's ``crc32part`` (no inversion), computed with zlib's table code for speed."""
    return zlib.crc32(data, crc ^ 0xFFFFFFFF) ^ 0xFFFFFFFF


class Nak(Exception):
    """A request refused: its ``MAV_FTP_ERR`` code and, for ``FailErrno``, the errno."""

    def __init__(self, code: int, err: int = 0) -> None:
        super().__init__(code, err)
        self.code = code
        self.err = err

    def data(self) -> bytes:
        """The NAK's data: the code, and the errno after ``FailErrno``."""
        return bytes((self.code, self.err)) if self.code == ERR_ERRNO else bytes((self.code,))


def _os_nak(exc: OSError) -> Nak:
    """PX4's mapping: ENOENT is FileNotFound, EEXIST FileExists, anything else FailErrno."""
    if exc.errno == errno.ENOENT:
        return Nak(ERR_NOT_FOUND)
    if exc.errno == errno.EEXIST:
        return Nak(ERR_EXISTS)
    return Nak(ERR_ERRNO, _NUTTX_ERRNO.get(exc.errno or 0, 5))


class _Target:
    """What a request's path names: a place on the SD card, or a virtual file or folder."""

    __slots__ = ("kind", "path", "with_defaults")

    def __init__(self, kind: str, path: Path, with_defaults: bool = False) -> None:
        self.kind = kind   # "sd", "sd_root", "param_file", "param_dir", "extra", "extras_dir"
        self.path = path
        self.with_defaults = with_defaults


class _Session:
    __slots__ = ("data", "fd", "readable", "size", "stream_chunk", "stream_offset",
                 "stream_seq", "streaming", "writable")

    def __init__(self, fd: int, data: bytes | None, size: int, readable: bool,
                 writable: bool) -> None:
        self.fd = fd                # -1 for a virtual file (its bytes are ``data``)
        self.data = data
        self.size = size            # at open, as PX4 (EOF is judged against it)
        self.readable = readable
        self.writable = writable
        self.streaming = False
        self.stream_offset = 0
        self.stream_seq = 0
        self.stream_chunk = 0

    def read(self, offset: int, n: int) -> bytes:
        if self.data is not None:
            return self.data[offset:offset + n]
        return os.pread(self.fd, n, offset)

    def close(self) -> None:
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1


def reply_payload(seq: int, session: int, opcode: int, req_opcode: int, offset: int,
                  data: bytes = b"", burst_complete: int = 0) -> bytes:
    """A 251-byte FILE_TRANSFER_PROTOCOL payload."""
    head = HEADER.pack(seq & 0xFFFF, session & 0xFF, opcode, len(data), req_opcode & 0xFF,
                       burst_complete, offset & 0xFFFFFFFF)
    return head + data + bytes(MAX_DATA - len(data))


class FtpServer:
    """The protocol without the link: a request payload in, the reply payload out.

    ``root`` is the SD card's host folder (None: no card, every file request is
    FileNotFound); ``params`` the board's parameters (or None) for ``@PARAM/param.pck``;
    ``extras`` gives ``/etc/extras``'s files by name (built when first asked for)."""

    def __init__(self, root: Path | None, params: Any,
                 extras: Callable[[], dict[str, bytes]] | None = None) -> None:
        self.root = root
        self.params = params
        self.extras = extras or dict
        self.session: _Session | None = None
        self._last_reply: bytes | None = None
        self._last_request = (0, 0, 0)   # (seq, opcode, session) of the cached reply
        self.last_request_us = 0
        self.requests = 0
        self.naks = 0

    # -- the entry point ----------------------------------------------------------------------

    def handle(self, payload: bytes, now_us: int) -> bytes | None:
        """Run one request; the reply payload, or None for a burst that has started (its
        packets come from :meth:`burst_packet`)."""
        req = bytes(payload[:PAYLOAD_LEN]).ljust(PAYLOAD_LEN, b"\x00")
        seq, session, opcode, size, _req_op, _bc, offset = HEADER.unpack_from(req)
        self.requests += 1
        self.last_request_us = now_us
        if self._last_reply is not None and self._last_request == (seq, opcode, session):
            return self._last_reply   # the reply was lost and the request repeated
        self._last_reply = None
        data = req[HDR_LEN:HDR_LEN + size]
        refused: Nak | None = None
        out: tuple[int, bytes] | None = None
        try:
            if size > MAX_DATA:
                raise Nak(ERR_DATA_SIZE)
            out = self._run(opcode, session, offset, data, seq)
        except Nak as exc:
            refused = exc
        except OSError as exc:
            refused = _os_nak(exc)
        if refused is not None:
            self.naks += 1
            reply = reply_payload(seq + 1, session, OP_NAK, opcode, offset, refused.data())
        elif out is None:
            return None
        else:
            reply = reply_payload(seq + 1, out[0], OP_ACK, opcode, offset, out[1])
        if reply[4] <= 4:  # the data size: keep small replies for a repeated request
            self._last_reply = reply
            self._last_request = (seq, opcode, session)
        return reply

    def _run(self, opcode: int, session: int, offset: int, data: bytes, seq: int
             ) -> tuple[int, bytes] | None:
        if opcode == OP_NONE:
            return session, b""
        if opcode == OP_TERMINATE:
            self._session(session).close()
            self.session = None
            return session, b""
        if opcode == OP_RESET:
            self.close()
            return session, b""
        if opcode == OP_LIST:
            return session, self._list(self._resolve(data), offset)
        if opcode in (OP_OPEN_RO, OP_CREATE, OP_OPEN_WO):
            return 0, struct.pack("<I", self._open(self._resolve(data), opcode))
        if opcode == OP_READ:
            return session, self._read(self._session(session), offset, len(data))
        if opcode == OP_BURST:
            s = self._session(session)
            if not s.readable:
                raise Nak(ERR_ERRNO, NUTTX_EBADF)
            s.streaming = True
            s.stream_offset = offset
            s.stream_seq = (seq + 1) & 0xFFFF
            s.stream_chunk = 0
            return None
        if opcode == OP_WRITE:
            return session, self._write(self._session(session), offset, data)
        if opcode == OP_CRC32:
            return session, struct.pack("<I", self._crc(self._resolve(data)))
        if opcode in (OP_REMOVE_FILE, OP_MKDIR, OP_RMDIR, OP_TRUNCATE, OP_RENAME):
            self._change(opcode, data, offset)
            return session, b""
        raise Nak(ERR_UNKNOWN)

    # -- paths ---------------------------------------------------------------------------------

    def _resolve(self, data: bytes) -> _Target:
        """The target of a path (C-string semantics: it ends at the first NUL)."""
        raw = data.split(b"\x00", 1)[0]
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError:
            raise Nak(ERR_ERRNO, NUTTX_EINVAL) from None
        bare = text.lstrip("/")
        if bare == PARAM_DIR or bare.startswith(PARAM_DIR + "/"):
            name, _, query = bare[len(PARAM_DIR) + 1:].partition("?")
            if name.strip("/") == "":
                return _Target("param_dir", Path("."))
            if name != PARAM_FILE or self.params is None:
                raise Nak(ERR_NOT_FOUND)
            return _Target("param_file", Path("."), query == "withdefaults=1")
        if bare.rstrip("/") == EXTRAS_DIR or bare.startswith(EXTRAS_DIR + "/"):
            name = bare[len(EXTRAS_DIR):].strip("/")
            if name and name not in self.extras():
                raise Nak(ERR_NOT_FOUND)
            return _Target("extra" if name else "extras_dir", Path(name))
        if bare == LOG_ALIAS or bare.startswith(LOG_ALIAS + "/"):
            text = "/log" + bare[len(LOG_ALIAS):]
        if self.root is None:
            raise Nak(ERR_NOT_FOUND)
        # ".." stops at the root, as POSIX's "/.." (one leading slash: normpath keeps "//")
        p = posixpath.normpath("/" + text.lstrip("/"))
        if p == SD_PREFIX or p.startswith(SD_PREFIX + "/"):
            p = p[len(SD_PREFIX):] or "/"
        rel = p.strip("/")
        if rel == "":
            return _Target("sd_root", self.root)
        path = self.root / rel
        real_root = os.path.realpath(self.root)
        real = os.path.realpath(path)
        if real != real_root and not real.startswith(real_root + os.sep):
            raise Nak(ERR_ERRNO, NUTTX_EACCES)   # a symbolic link out of the card
        return _Target("sd", path)

    # -- operations -----------------------------------------------------------------------------

    def _session(self, session: int) -> _Session:
        s = self.session
        if session != 0 or s is None:
            raise Nak(ERR_SESSION)
        return s

    def _list(self, t: _Target, offset: int) -> bytes:
        """Entries from ``offset`` (an entry count): ``F name<TAB>size``, ``D name``, each
        NUL-terminated, as many as fit; NAK EOF when none is left. (PX4 answers an empty
        folder at offset 0 with an empty ACK; the protocol ends every listing with EOF, and
        pymavlink would ask again for ever, so the emulator sends EOF.)"""
        if t.kind == "param_dir":
            entries = [f"F{PARAM_FILE}\t{len(self._param_bytes(False))}"]
        elif t.kind == "extras_dir":
            entries = [f"F{name}\t{len(data)}" for name, data in sorted(self.extras().items())]
        else:
            if not t.path.is_dir():
                raise Nak(ERR_NOT_FOUND)
            entries = []
            for e in sorted(os.scandir(t.path), key=lambda e: e.name):
                if e.is_dir(follow_symlinks=False):
                    entries.append("D" + e.name)
                elif e.is_file(follow_symlinks=False):
                    entries.append(f"F{e.name}\t{e.stat(follow_symlinks=False).st_size}")
                else:
                    entries.append("S")       # PX4 skips everything else, keeping its place
        if offset >= len(entries):
            raise Nak(ERR_EOF)
        out = bytearray()
        for text in entries[offset:]:
            raw = text.encode("utf-8", "surrogateescape")
            if len(raw) + 1 > MAX_DATA:
                raw = b"S"                     # a name too long for any reply: skipped
            if len(out) + len(raw) + 1 > MAX_DATA:
                break
            out += raw + b"\x00"
        return bytes(out)

    def _param_bytes(self, with_defaults: bool) -> bytes:
        return pack_params(self.params, with_defaults) if self.params is not None else b""

    def _virtual(self, t: _Target) -> bytes | None:
        """A virtual file's bytes (None for a place that is not one)."""
        if t.kind == "param_file":
            return self._param_bytes(t.with_defaults)
        return self.extras()[t.path.name] if t.kind == "extra" else None

    def _open(self, t: _Target, opcode: int) -> int:
        if self.session is not None:
            raise Nak(ERR_NO_SESSIONS)
        data = self._virtual(t)
        if data is not None:
            if opcode != OP_OPEN_RO:
                raise Nak(ERR_PROTECTED)
            self.session = _Session(-1, data, len(data), True, False)
            return len(data)
        if t.kind != "sd":
            raise Nak(ERR_ERRNO, NUTTX_EISDIR)
        if t.path.is_dir():
            raise Nak(ERR_ERRNO, NUTTX_EISDIR)
        if opcode == OP_OPEN_RO:
            size = t.path.stat().st_size
            fd = os.open(t.path, os.O_RDONLY)
            self.session = _Session(fd, None, size, True, False)
            return size
        flags = os.O_RDWR | os.O_CREAT | (os.O_TRUNC if opcode == OP_CREATE else 0)
        fd = os.open(t.path, flags, 0o666)
        size = os.fstat(fd).st_size
        self.session = _Session(fd, None, size, True, True)
        return size

    def _read(self, s: _Session, offset: int, n: int) -> bytes:
        """ReadFile: ``size`` bytes (0: as many as fit) from ``offset``; EOF at or past the
        end of the file as it was opened (PX4 tests that itself: lseek would allow it)."""
        if not s.readable:
            raise Nak(ERR_ERRNO, NUTTX_EBADF)
        if offset >= s.size:
            raise Nak(ERR_EOF)
        return s.read(offset, n if n > 0 else MAX_DATA)

    def _write(self, s: _Session, offset: int, data: bytes) -> bytes:
        if not s.writable:
            raise Nak(ERR_ERRNO, NUTTX_EBADF)
        if offset + len(data) > MAX_FILE_BYTES:
            raise Nak(ERR_ERRNO, NUTTX_EFBIG)
        n = os.pwrite(s.fd, data, offset)
        s.size = max(s.size, offset + n)
        return struct.pack("<I", n)

    def _crc(self, t: _Target) -> int:
        data = self._virtual(t)
        if data is not None:
            return crc32_px4(data)
        if t.kind != "sd" or t.path.is_dir():
            raise Nak(ERR_ERRNO, NUTTX_EISDIR)
        crc = 0
        with open(t.path, "rb") as f:
            while True:
                block = f.read(1 << 16)
                if not block:
                    return crc
                crc = crc32_px4(block, crc)

    def _change(self, opcode: int, data: bytes, offset: int) -> None:
        """RemoveFile, CreateDirectory, RemoveDirectory, TruncateFile, Rename: on the SD card
        only (a virtual file or the card's root is FileProtected)."""
        t = self._resolve(data)
        if t.kind != "sd":
            raise Nak(ERR_PROTECTED)
        p = t.path
        if opcode == OP_REMOVE_FILE:
            if p.is_dir():
                raise Nak(ERR_ERRNO, NUTTX_EISDIR)
            os.unlink(p)
        elif opcode == OP_MKDIR:
            os.mkdir(p)
        elif opcode == OP_RMDIR:
            os.rmdir(p)
        elif opcode == OP_TRUNCATE:
            if p.is_dir():
                raise Nak(ERR_ERRNO, NUTTX_EISDIR)
            if offset > MAX_FILE_BYTES:
                raise Nak(ERR_ERRNO, NUTTX_EFBIG)
            if not p.exists():
                raise Nak(ERR_NOT_FOUND)
            os.truncate(p, offset)
        else:  # rename: "old\0new"
            parts = data.split(b"\x00")
            if len(parts) < 2 or parts[1] == b"":
                raise Nak(ERR_ERRNO, NUTTX_EINVAL)    # PX4: no new path is EINVAL
            new = self._resolve(parts[1])
            if new.kind != "sd":
                raise Nak(ERR_PROTECTED)
            os.rename(p, new.path)

    # -- burst and housekeeping ----------------------------------------------------------------

    def streaming(self) -> bool:
        return self.session is not None and self.session.streaming

    def burst_packet(self) -> bytes | None:
        """The next packet of a running burst (None if none runs). The caller sends it and
        then calls :meth:`burst_sent`; a packet the link could not take is built again."""
        s = self.session
        if s is None or not s.streaming:
            return None
        if s.stream_offset >= s.size:
            return reply_payload(s.stream_seq, 0, OP_NAK, OP_BURST, s.stream_offset,
                                 bytes((ERR_EOF,)))
        try:
            chunk = s.read(s.stream_offset, MAX_DATA)
        except OSError as exc:
            return reply_payload(s.stream_seq, 0, OP_NAK, OP_BURST, s.stream_offset,
                                 _os_nak(exc).data())
        if not chunk:   # the file shrank since it was opened
            return reply_payload(s.stream_seq, 0, OP_NAK, OP_BURST, s.stream_offset,
                                 bytes((ERR_EOF,)))
        last = s.stream_chunk + len(chunk) > BURST_CHUNK_BYTES
        return reply_payload(s.stream_seq, 0, OP_ACK, OP_BURST, s.stream_offset, chunk,
                             1 if last else 0)

    def burst_sent(self, packet: bytes) -> None:
        """Advance the burst past ``packet`` (from :meth:`burst_packet`), which went out."""
        s = self.session
        if s is None:
            return
        s.stream_seq = (s.stream_seq + 1) & 0xFFFF
        if packet[3] == OP_NAK or packet[6]:   # opcode NAK, or burst_complete
            s.streaming = False
            if packet[3] != OP_NAK:
                s.stream_offset += packet[4]
            s.stream_chunk = 0
            return
        s.stream_offset += packet[4]
        s.stream_chunk += packet[4]

    def idle(self, now_us: int) -> None:
        """PX4 closes a session that has had no request for 10 s (a client gone away)."""
        if self.session is not None and not self.session.streaming and \
                now_us - self.last_request_us > SESSION_TIMEOUT_US:
            self.close()

    def close(self) -> None:
        if self.session is not None:
            self.session.close()
            self.session = None


#: burst packets per link run at most (the data rate limits them further)
BURST_PACKETS_PER_RUN: Final = 32


class FtpService:
    """FILE_TRANSFER_PROTOCOL on one link (PX4 runs one ``MavlinkFTP`` per link): requests
    answered at once (an answer needs only room in the transmit buffer), burst packets sent
    as the link's data rate allows, as the log download's are."""

    def __init__(self, inst: MavlinkInstance) -> None:
        self.inst = inst
        from firmware.modules.mavlink.component_metadata import ComponentMetadata

        sd = inst.system.sd_root
        #: the component metadata files (also what COMPONENT_METADATA describes)
        self.metadata = ComponentMetadata(inst.system.params)
        self.server = FtpServer(None if sd is None else Path(sd), inst.system.params,
                                self.metadata.files)
        self._burst_target = (0, 0)

    def handlers(self) -> dict[int, Callable[[Any], None]]:
        return {mav.MAVLINK_MSG_ID_FILE_TRANSFER_PROTOCOL: self._on_ftp}

    def _send(self, payload: bytes, target: tuple[int, int], budget: bool) -> bool:
        return self.inst.send(mav.MAVLink_file_transfer_protocol_message(
            0, target[0], target[1], list(payload)), budget=budget)

    def _on_ftp(self, m: Any) -> None:
        target = (m.get_srcSystem(), m.get_srcComponent())
        reply = self.server.handle(bytes(m.payload), self.inst.time_us())
        if reply is None:
            self._burst_target = target   # a burst started: update() streams it
            return
        self._send(reply, target, False)

    def update(self, now_us: int) -> None:
        srv = self.server
        srv.idle(now_us)
        for _ in range(BURST_PACKETS_PER_RUN):
            packet = srv.burst_packet()
            if packet is None or not self._send(packet, self._burst_target, True):
                return
            srv.burst_sent(packet)
