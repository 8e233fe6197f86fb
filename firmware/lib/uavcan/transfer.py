"""DroneCAN transfers over emulated CAN frames, with the ``dronecan`` package's serialisation.

The package gives the DSDL types (``dronecan.uavcan.protocol.NodeStatus`` ...), their bit-exact
serialisation and :class:`dronecan.transport.Transfer`, which splits a transfer into frames
(transfer CRC seeded with the data type's signature, toggle bits, tail bytes) and checks and
decodes a complete frame list. What it does not give an emulated board is the receive side
in virtual time: its ``TransferManager`` times transfers out on the wall clock and a bad
transfer raises. :class:`Reassembler` does that part: per source (the CAN ID holds the
source, the data type and, for services, the destination) it gathers the frames of a transfer
as they arrive, checks the tail byte of each (start, toggle alternating from 0, same transfer
ID, full frames before the last), drops a transfer left unfinished for 2 s (the spec's
transfer timeout) and hands the finished frames to ``Transfer.from_frames`` for the CRC and
the decoding. Every bad frame or transfer is counted by cause and dropped: a bus carries what
any node sends.

The ``dronecan`` package reads the wall clock only in its Node and TransferManager, which are
not used here (serialisation only), so the boards stay deterministic.
"""

from __future__ import annotations

from typing import Any, Final

import can
import dronecan
import dronecan.transport as dtransport
from dronecan.dsdl import common as dcommon

from firmware.lib.uavcan.ids import (
    PRIORITY_DEFAULT,
    TAIL_EOT,
    TAIL_SOT,
    TAIL_TOGGLE,
    parse_id,
)

__all__ = ["ERROR_KINDS", "Reassembler", "RxTransfer", "TransferIds", "decode_single",
           "encode", "types"]

#: The spec's transfer timeout: frames of an unfinished transfer older than this are dropped.
TRANSFER_TIMEOUT_NS: Final = 2_000_000_000
#: Transfers being reassembled at once (a node talks to a handful of peers; a flood of
#: starts from random IDs must not grow memory without bound).
MAX_PENDING: Final = 32
#: Why a frame or transfer was dropped (the counters of :class:`Reassembler`).
ERROR_KINDS: Final[tuple[str, ...]] = (
    "bad_crc", "bad_toggle", "bad_length", "unknown_type", "bad_payload", "bad_tail",
    "missed_start", "timeouts", "evicted")


def types() -> Any:
    """The package's DSDL namespace root (``types().uavcan.protocol.NodeStatus``)."""
    return dronecan


def _discriminator(payload: bytes) -> int:
    # anonymous transfers carry a discriminator so that two anonymous nodes sending at once
    # collide less: derived from the payload, as libcanard does
    return int(dcommon.crc16_from_bytes(payload)) & 0x3FFF


def encode(obj: Any, source: int, transfer_id: int, priority: int = PRIORITY_DEFAULT,
           dest: int | None = None) -> list[can.Message]:
    """The frames of one transfer of ``obj`` (a message, or a service ``Request()`` /
    ``Response()`` sent to ``dest``) from ``source`` (0: anonymous, single frame only)."""
    kind = dtransport.get_dronecan_data_type(obj)
    service = kind.kind == kind.KIND_SERVICE
    if service:
        if dest is None:
            raise ValueError(f"{kind.full_name}: a service transfer needs a destination")
        mode = getattr(obj, "_mode", "request")
        tr = dtransport.Transfer(payload=obj, source_node_id=source, dest_node_id=dest,
                                 transfer_id=transfer_id & 0x1F, transfer_priority=priority,
                                 service_not_message=True,
                                 request_not_response=mode == "request")
    elif source == 0:
        tr = dtransport.Transfer(payload=obj, source_node_id=0, transfer_id=transfer_id & 0x1F,
                                 transfer_priority=priority, discriminator=0)
        tr.discriminator = _discriminator(bytes(tr.payload))
        if len(tr.payload) > 7:
            raise ValueError(f"{kind.full_name}: an anonymous transfer must fit one frame "
                             f"({len(tr.payload)} bytes)")
    else:
        tr = dtransport.Transfer(payload=obj, source_node_id=source,
                                 transfer_id=transfer_id & 0x1F, transfer_priority=priority)
    return [can.Message(arbitration_id=f.message_id, is_extended_id=True, data=bytes(f.bytes))
            for f in tr.to_frames()]


class RxTransfer:
    """A received transfer: who sent it, to whom, and the decoded DSDL object."""

    __slots__ = ("t_ns", "source", "dest", "service", "request", "data_type_id", "transfer_id",
                 "priority", "payload", "frames", "tr")

    def __init__(self, t_ns: int, tr: Any, frames: int) -> None:
        self.t_ns = t_ns
        self.source: int = tr.source_node_id
        self.dest: int | None = tr.dest_node_id if tr.service_not_message else None
        self.service: bool = bool(tr.service_not_message)
        self.request: bool = bool(tr.request_not_response)
        self.data_type_id: int = tr.data_type_id
        self.transfer_id: int = tr.transfer_id
        self.priority: int = tr.transfer_priority
        self.payload: Any = tr.payload
        self.frames = frames
        self.tr: Any = tr  # the dronecan Transfer (shared by the receivers of one frame)

    @property
    def type_name(self) -> str:
        return str(dtransport.get_dronecan_data_type(self.payload).full_name)

    def __repr__(self) -> str:
        return (f"<RxTransfer {self.type_name} from {self.source} to {self.dest} "
                f"tid {self.transfer_id}>")


class _Pending:
    __slots__ = ("t_ns", "tid", "toggle", "frames", "size", "max_size")

    def __init__(self, t_ns: int, tid: int, first: Any, max_size: int) -> None:
        self.t_ns = t_ns
        self.tid = tid
        self.toggle = TAIL_TOGGLE
        self.frames = [first]
        self.size = len(first.bytes) - 1
        self.max_size = max_size


class Reassembler:
    """Frames in, complete transfers out, for a node whose ID is ``node_id`` (0 while it has
    none: it still hears messages and anonymous messages, but no service is addressed to it),
    keeping the messages whose data type is in ``accept`` (all when None).

    :meth:`push` returns the decoded :class:`RxTransfer` when a frame completes one, else None.
    ``errors`` counts what was dropped, by cause (:data:`ERROR_KINDS`).
    """

    def __init__(self, node_id: int = 0, accept: frozenset[int] | None = None) -> None:
        self.node_id = node_id
        #: message data type IDs this node wants (its acceptance filter: others are skipped
        #: before any decoding, counted in ``not_for_us``); None takes every message
        self.accept = accept
        self.frames = 0
        self.transfers = 0
        self.not_for_us = 0
        self.errors: dict[str, int] = dict.fromkeys(ERROR_KINDS, 0)
        self._pending: dict[int, _Pending] = {}

    @property
    def error_count(self) -> int:
        return sum(self.errors.values())

    def _drop(self, kind: str) -> None:
        self.errors[kind] += 1

    def push(self, msg: can.Message, t_ns: int) -> RxTransfer | None:
        self.frames += 1
        data = bytes(msg.data)
        if not msg.is_extended_id or msg.is_remote_frame or not data:
            self._drop("bad_length")  # not a DroneCAN frame: no tail byte, or an 11-bit ID
            return None
        cid = parse_id(msg.arbitration_id)
        if cid.service:
            if cid.source == 0 or cid.dest == 0:
                self._drop("bad_tail")
                return None
            if cid.dest != self.node_id:
                self.not_for_us += 1
                return None
        elif self.accept is not None and cid.source and cid.data_type_id not in self.accept:
            self.not_for_us += 1
            return None
        tail = data[-1]
        key = msg.arbitration_id & 0x1FFFFFFF
        frame = dtransport.Frame(key, data)
        if tail & TAIL_SOT:
            datatype = dronecan.DATATYPES.get(
                (cid.data_type_id, 0 if cid.service else 1))
            if datatype is None:
                self._pending.pop(key, None)
                self._drop("unknown_type")
                return None
            if tail & TAIL_EOT:
                self._pending.pop(key, None)
                if tail & TAIL_TOGGLE:
                    self._drop("bad_toggle")
                    return None
                memo = _SINGLE
                if memo.key == (key, data):  # the frame every other node on the bus just took
                    self.transfers += 1
                    return RxTransfer(t_ns, memo.tr, 1)
                got = self._decode(t_ns, [frame])
                if got is not None:
                    memo.key, memo.tr = (key, data), got.tr
                return got
            if cid.anonymous:
                self._drop("bad_tail")  # anonymous transfers are single-frame
                return None
            if len(data) != 8:
                self._drop("bad_length")
                return None
            if key not in self._pending and len(self._pending) >= MAX_PENDING:
                self._evict(t_ns)
            self._pending[key] = _Pending(t_ns, tail & 0x1F, frame, _max_bytes(datatype, cid))
            return None
        p = self._pending.get(key)
        if p is not None and t_ns - p.t_ns > TRANSFER_TIMEOUT_NS:
            del self._pending[key]
            self._drop("timeouts")
            p = None
        if p is None or p.tid != tail & 0x1F:
            self._drop("missed_start")
            return None
        if tail & TAIL_TOGGLE != p.toggle:
            del self._pending[key]
            self._drop("bad_toggle")
            return None
        if not tail & TAIL_EOT and len(data) != 8:
            del self._pending[key]
            self._drop("bad_length")
            return None
        p.frames.append(frame)
        p.toggle ^= TAIL_TOGGLE
        p.size += len(data) - 1
        if p.size > p.max_size:
            del self._pending[key]
            self._drop("bad_length")
            return None
        if not tail & TAIL_EOT:
            return None
        del self._pending[key]
        return self._decode(t_ns, p.frames)

    def _evict(self, t_ns: int) -> None:
        oldest = min(self._pending, key=lambda k: self._pending[k].t_ns)
        stale = t_ns - self._pending[oldest].t_ns > TRANSFER_TIMEOUT_NS
        del self._pending[oldest]
        self._drop("timeouts" if stale else "evicted")

    def _decode(self, t_ns: int, frames: list[Any]) -> RxTransfer | None:
        tr = dtransport.Transfer()
        try:
            tr.from_frames(frames)
        except dtransport.TransferError as e:
            text = str(e)
            self._drop("bad_crc" if "CRC" in text else "bad_toggle" if "Toggle" in text
                       else "unknown_type" if "Unrecognised" in text else "bad_tail")
            return None
        except (ValueError, IndexError, KeyError, TypeError, OverflowError):
            self._drop("bad_payload")  # too few bits for the type, an array length too long
            return None
        self.transfers += 1
        return RxTransfer(t_ns, tr, len(frames))


class _SingleFrameMemo:
    """The last single-frame transfer decoded, by (CAN ID, bytes): a broadcast reaches every
    node on the bus at once (four ESCs take each RawCommand), and decoding it once saves the
    dronecan package's DSDL decoding for the others. The decoded object is shared: receivers
    read it and never modify it. Pure (no state beyond the last frame), so deterministic."""

    __slots__ = ("key", "tr")

    def __init__(self) -> None:
        self.key: tuple[int, bytes] | None = None
        self.tr: Any = None


_SINGLE: Final = _SingleFrameMemo()


def _max_bytes(datatype: Any, cid: Any) -> int:
    """The longest payload of the type in this direction, plus the transfer CRC."""
    if not cid.service:
        bits = datatype.get_max_bitlen()
    elif cid.request:
        bits = datatype.get_max_bitlen_request()
    else:
        bits = datatype.get_max_bitlen_response()
    return (int(bits) + 7) // 8 + 2


def decode_single(msg: can.Message, t_ns: int = 0) -> RxTransfer | None:
    """A single-frame transfer's decoded contents (any destination), else None."""
    r = Reassembler()
    cid = parse_id(msg.arbitration_id) if msg.is_extended_id else None
    if cid is not None and cid.service and cid.dest is not None:
        r.node_id = cid.dest
    return r.push(msg, t_ns)


class TransferIds:
    """Per (data type, kind, destination) transfer-ID counters, modulo 32, as the spec asks:
    a receiver tells a repeated transfer from a new one by them."""

    def __init__(self) -> None:
        self._next: dict[tuple[int, bool, int], int] = {}

    def next(self, data_type_id: int, service: bool = False, dest: int = 0) -> int:
        key = (data_type_id, service, dest)
        tid = self._next.get(key, 0)
        self._next[key] = (tid + 1) & 0x1F
        return tid
