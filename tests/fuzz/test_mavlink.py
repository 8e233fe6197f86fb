"""Fuzz targets for the FMU's MAVLink link: the receive path, the mission protocol, commands
and the MAVLink shell, each fed through a real link of one booted FMU (shared by the module:
a boot takes ~0.8 s, an example a few virtual milliseconds).

Every target checks, after each example, that no message handler raised (every guard that
contains a handler's exception, the dispatcher's, the mission protocol's and the commands',
reports it to the instance: ``rx_handler_errors`` and an ERR line of ``mavlink`` in dmesg, even
when the GCS got a polite MISSION_ERROR or MAV_RESULT_FAILED) and that the board is alive;
then what its part of the protocol promises.
"""

from __future__ import annotations

import math
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pymavlink.dialects.v10 import common as mav1
from pymavlink.dialects.v20 import common as mav

from firmware.modules.mavlink.mission import SUPPORTED_NAV_CMDS, check_item
from tests.fuzzing import fuzz
from tests.mavlink.conftest import open_session


class _Sink:
    def write(self, data: bytes) -> None:  # pymavlink's packers want a file
        pass


@pytest.fixture(scope="module")
def fmu(tmp_path_factory):
    s = open_session(tmp_path_factory.mktemp("fuzz_mavlink"))
    s.gcs.wait_heartbeat()
    if "dataman: running" not in s.orch.call("fmu", "shell", "dataman status")[1]:
        s.shell("dataman start")
    s.shell("commander start")
    s.gcs.step(0.3)
    yield s
    s.close()


def _instance(s: Any) -> Any:
    return s.udp_instance()


def _store(s: Any) -> Any:
    return s.orch.handles["fmu"].endpoint.board.system.modules.get("dataman").store


def _mark(s: Any) -> tuple[int, int]:
    """What :func:`_healthy` compares with: the handler error count and the dmesg time."""
    return _instance(s).rx_handler_errors, s.dmesg_mark()


def _healthy(s: Any, before: tuple[int, int]) -> None:
    assert not s.orch.dead, f"the FMU died: {s.orch.dead}"
    errors, since_us = before
    assert s.mavlink_errors(since_us) == [], "a MAVLink handler raised"
    assert _instance(s).rx_handler_errors == errors, "a MAVLink handler raised"


def _answers(s: Any) -> None:
    """The link still takes a HEARTBEAT (the GCS is heard) and answers a parameter read and
    a command."""
    gcs = s.gcs
    inst = _instance(s)
    heard_us = inst.gcs_heartbeat_us
    gcs.send(mav.MAVLink_heartbeat_message(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0,
                                           mav.MAV_STATE_ACTIVE, 3))
    assert gcs.param_get("MAV_SYS_ID", timeout_s=0.5) == 1
    assert inst.gcs_heartbeat_us > heard_us and inst.gcs_sysid == 255
    ack = gcs.command_long(mav.MAV_CMD_REQUEST_MESSAGE, [mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION],
                           timeout_s=0.5, retries=0)
    assert ack.result == mav.MAV_RESULT_ACCEPTED


# -- the receive path ------------------------------------------------------------------------

_V1 = mav1.MAVLink(_Sink(), 255, 190)
_V2 = mav.MAVLink(_Sink(), 255, 190)


def _templates() -> list[bytes]:
    """Real frames, v1 and v2, of messages the FMU handles (none that changes its set-up:
    no PARAM_SET, SETUP_SIGNING or reboot)."""
    out = []
    for dialect, codec in ((mav1, _V1), (mav, _V2)):
        msgs = [
            dialect.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3),
            dialect.MAVLink_param_request_read_message(1, 1, b"MAV_SYS_ID", -1),
            dialect.MAVLink_param_request_read_message(1, 1, b"", 7),
            dialect.MAVLink_command_long_message(1, 1, 512, 0, 148, 0, 0, 0, 0, 0, 0),
            dialect.MAVLink_mission_request_list_message(1, 1),
            dialect.MAVLink_mission_request_int_message(1, 1, 0),
            dialect.MAVLink_ping_message(1, 2, 0, 0),
            dialect.MAVLink_timesync_message(0, 42),
            dialect.MAVLink_attitude_message(0, 0.1, 0.2, 0.3, 0, 0, 0),
            dialect.MAVLink_serial_control_message(10, 6, 0, 0, 1, [10] + [0] * 69),
        ]
        out += [bytes(m.pack(codec)) for m in msgs]
    return out


TEMPLATES = _templates()


@st.composite
def _mutated_frames(draw: Any) -> bytes:
    """Real frames spliced together, with bits flipped and cut short."""
    frames = draw(st.lists(st.sampled_from(TEMPLATES), min_size=1, max_size=4))
    data = bytearray(b"".join(frames))
    for _ in range(draw(st.integers(0, 4))):
        pos = draw(st.integers(0, len(data) - 1))
        data[pos] ^= 1 << draw(st.integers(0, 7))
    if draw(st.booleans()):
        lo = draw(st.integers(0, len(data)))
        hi = draw(st.integers(lo, len(data)))
        data = data[:lo] + data[hi:] if draw(st.booleans()) else data[lo:hi]
    return bytes(data)


_DATAGRAMS = st.lists(st.one_of(st.binary(max_size=300), _mutated_frames(),
                                st.sampled_from(TEMPLATES)), min_size=1, max_size=4)


@fuzz(examples=100)
@given(datagrams=_DATAGRAMS)
def test_receive_path_survives_any_bytes(fmu, datagrams):
    """Invariant: random bytes and mutated, truncated or spliced v1/v2 frames never make a
    handler raise or the board die; after a frame's worth of idle bytes (a truncated frame
    swallows up to its announced length, as in PX4's parser) the link answers a valid
    PARAM_REQUEST_READ and COMMAND_LONG."""
    marked = _mark(fmu)
    for d in datagrams:
        fmu.gcs.send_bytes(d)
    fmu.gcs.send_bytes(bytes(280))
    fmu.gcs.step(0.02)
    _healthy(fmu, marked)
    _answers(fmu)


# -- every handled message, well framed, with any field values ----------------------------

#: handled messages left out: PARAM_SET would change the shared board's set-up (its fuzzing is
#: the parameter service's own target), SETUP_SIGNING would make it refuse the checks' unsigned
#: messages; commands, missions and the shell have targets of their own below
_LEFT_OUT = frozenset({mav.MAVLINK_MSG_ID_PARAM_SET, mav.MAVLINK_MSG_ID_SETUP_SIGNING,
                       mav.MAVLINK_MSG_ID_COMMAND_LONG, mav.MAVLINK_MSG_ID_COMMAND_INT,
                       mav.MAVLINK_MSG_ID_SERIAL_CONTROL})
_INT_RANGES = {"int8_t": (-2**7, 2**7 - 1), "uint8_t": (0, 2**8 - 1),
               "int16_t": (-2**15, 2**15 - 1), "uint16_t": (0, 2**16 - 1),
               "int32_t": (-2**31, 2**31 - 1), "uint32_t": (0, 2**32 - 1),
               "int64_t": (-2**63, 2**63 - 1), "uint64_t": (0, 2**64 - 1)}


def _field(ftype: str, length: int) -> Any:
    if ftype == "char":
        return st.binary(max_size=max(length, 1))
    if ftype in ("float", "double"):
        one: Any = _F32 if ftype == "float" else st.floats()
    else:
        lo, hi = _INT_RANGES[ftype]
        one = st.one_of(st.integers(lo, hi), st.sampled_from([lo, hi, 0]))
    return st.lists(one, min_size=length, max_size=length) if length else one


@st.composite
def _any_handled_message(draw: Any, ids: list[int]) -> Any:
    cls = mav.mavlink_map[draw(st.sampled_from(ids))]
    lengths = dict(zip(cls.ordered_fieldnames, cls.array_lengths))  # in wire order
    args = [draw(_field(t, lengths[name])) for name, t in zip(cls.fieldnames, cls.fieldtypes)]
    for i, name in enumerate(cls.fieldnames):  # mostly for us, so the handlers run
        if name in ("target_system", "target_component") and draw(st.integers(0, 3)):
            args[i] = 1
    return cls(*args)


def _handled_ids() -> list[int]:
    from firmware.modules.mavlink.instance import MavlinkInstance  # noqa: F401 (the table)

    return sorted(set(_HANDLED) - _LEFT_OUT)


#: the messages an instance has handlers for (checked against the live table by the test)
_HANDLED = (mav.MAVLINK_MSG_ID_HEARTBEAT, mav.MAVLINK_MSG_ID_PING, mav.MAVLINK_MSG_ID_TIMESYNC,
            mav.MAVLINK_MSG_ID_PARAM_REQUEST_LIST, mav.MAVLINK_MSG_ID_PARAM_REQUEST_READ,
            mav.MAVLINK_MSG_ID_MISSION_COUNT, mav.MAVLINK_MSG_ID_MISSION_ITEM,
            mav.MAVLINK_MSG_ID_MISSION_ITEM_INT, mav.MAVLINK_MSG_ID_MISSION_REQUEST_LIST,
            mav.MAVLINK_MSG_ID_MISSION_REQUEST, mav.MAVLINK_MSG_ID_MISSION_REQUEST_INT,
            mav.MAVLINK_MSG_ID_MISSION_ACK, mav.MAVLINK_MSG_ID_MISSION_CLEAR_ALL,
            mav.MAVLINK_MSG_ID_MISSION_SET_CURRENT, mav.MAVLINK_MSG_ID_LOG_REQUEST_LIST,
            mav.MAVLINK_MSG_ID_LOG_REQUEST_DATA, mav.MAVLINK_MSG_ID_LOG_REQUEST_END,
            mav.MAVLINK_MSG_ID_LOG_ERASE, mav.MAVLINK_MSG_ID_MANUAL_CONTROL,
            mav.MAVLINK_MSG_ID_SET_ATTITUDE_TARGET,
            mav.MAVLINK_MSG_ID_SET_POSITION_TARGET_LOCAL_NED,
            mav.MAVLINK_MSG_ID_SET_POSITION_TARGET_GLOBAL_INT)


@fuzz(examples=80)
@given(msgs=st.lists(_any_handled_message(_handled_ids()), min_size=1, max_size=4))
def test_handled_messages_with_any_fields(fmu, msgs):
    """Invariant: every message the link handles (but PARAM_SET and SETUP_SIGNING), validly
    framed with any field values (NaN, infinity, extremes, any target), never makes a handler
    raise or the board die, and the link still answers a parameter read and a command."""
    handled = set(_instance(fmu).handlers)
    assert set(_HANDLED) - handled == set(), "a handler went away: update _HANDLED"
    marked = _mark(fmu)
    for m in msgs:
        fmu.gcs.send(m)
    fmu.gcs.step(0.02)
    _healthy(fmu, marked)
    _answers(fmu)


# -- the mission protocol ----------------------------------------------------------------

_F32 = st.one_of(st.floats(width=32),
                 st.sampled_from([math.nan, math.inf, -math.inf, 3.4e38, -3.4e38, 0.0, -1.0]))
_FRAMES = st.one_of(st.sampled_from([0, 2, 3, 5, 6]), st.integers(0, 255))
_CMDS = st.one_of(st.sampled_from(sorted(SUPPORTED_NAV_CMDS)), st.integers(0, 65535))
_LAT_E7 = st.one_of(st.integers(-900_000_000, 900_000_000), st.integers(-2**31, 2**31 - 1))
_LON_E7 = st.one_of(st.integers(-1_800_000_000, 1_800_000_000), st.integers(-2**31, 2**31 - 1))


@st.composite
def _item(draw: Any, seq: int) -> Any:
    """A MISSION_ITEM_INT or MISSION_ITEM, mostly plausible, sometimes not at all."""
    cmd, frame = draw(_CMDS), draw(_FRAMES)
    p = [draw(_F32) for _ in range(4)]
    z = draw(_F32)
    mtype = draw(st.sampled_from([0, 0, 0, 0, 1, 255]))
    seq = draw(st.sampled_from([seq, seq, seq, min(seq + 1, 65535), max(seq - 1, 0)]))
    if draw(st.booleans()):
        return mav.MAVLink_mission_item_int_message(1, 1, seq, frame, cmd, draw(st.integers(0, 1)),
                                                    1, *p, draw(_LAT_E7), draw(_LON_E7), z,
                                                    mtype)
    x = draw(st.one_of(st.floats(-90, 90, width=32), _F32))
    y = draw(st.one_of(st.floats(-180, 180, width=32), _F32))
    return mav.MAVLink_mission_item_message(1, 1, seq, frame, cmd, 0, 1, *p, x, y, z, mtype)


@st.composite
def _mission_messages(draw: Any) -> list[Any]:
    """An upload (MISSION_COUNT then its items in order, some bad) or a single stray message."""
    kind = draw(st.sampled_from(["upload", "upload", "count", "item", "request", "clear", "ack",
                                 "current"]))
    if kind == "upload":
        n = draw(st.integers(1, 5))
        return [mav.MAVLink_mission_count_message(1, 1, n, 0)] + \
            [draw(_item(seq)) for seq in range(n)]
    if kind == "count":
        return [mav.MAVLink_mission_count_message(1, 1, draw(st.integers(0, 65535)),
                                                  draw(st.sampled_from([0, 1, 2, 255])))]
    if kind == "item":
        return [draw(_item(draw(st.integers(0, 65535))))]
    if kind == "request":
        cls = draw(st.sampled_from([mav.MAVLink_mission_request_int_message,
                                    mav.MAVLink_mission_request_message]))
        return [cls(1, 1, draw(st.integers(0, 65535)), draw(st.sampled_from([0, 1])))]
    if kind == "clear":
        return [mav.MAVLink_mission_clear_all_message(1, 1, draw(st.sampled_from([0, 1, 255])))]
    if kind == "ack":
        return [mav.MAVLink_mission_ack_message(1, 1, draw(st.integers(0, 255)), 0)]
    return [mav.MAVLink_mission_set_current_message(1, 1, draw(st.integers(0, 65535)))]


def _snapshot(store: Any) -> list[bytes]:
    return [it.pack() for it in store.items()]


def _valid(store: Any) -> bool:
    for it in store.items():
        cmd = int(it.nav_cmd)
        frame = 3 if it.altitude_is_relative else 0
        if check_item(cmd, frame, (it.time_inside, it.acceptance_radius, it.loiter_radius,
                                   math.degrees(it.yaw) if math.isfinite(it.yaw) else math.nan),
                      it.lat, it.lon, it.altitude) != mav.MAV_MISSION_ACCEPTED:
            return False
    return True


def _download(s: Any, as_int: bool) -> list[Any]:
    """A whole download, every request in one datagram; each item must come back. An upload
    still in progress makes the vehicle ignore the request with a STATUSTEXT, as PX4 does:
    the GCS then cancels it (MISSION_ACK OPERATION_CANCELLED) and downloads again."""
    gcs = s.gcs
    for _ in range(2):
        mark = gcs.mark()
        gcs.send(mav.MAVLink_mission_request_list_message(1, 1, 0))
        answer = gcs.wait_for(lambda: next(iter(
            [m for m in gcs.messages(None, mark) if m.get_type() == "MISSION_COUNT" or (
                m.get_type() == "STATUSTEXT" and "ignored, already active" in m.text)]), None),
            0.5)
        if answer.get_type() == "MISSION_COUNT":
            break
        gcs.send(mav.MAVLink_mission_ack_message(1, 1, mav.MAV_MISSION_OPERATION_CANCELLED, 0))
    else:
        raise AssertionError("the download was refused after the upload was cancelled")
    count = answer.count
    mark = gcs.mark()
    req = mav.MAVLink_mission_request_int_message if as_int else \
        mav.MAVLink_mission_request_message
    for seq in range(count):
        gcs.send(req(1, 1, seq, 0))
    name = "MISSION_ITEM_INT" if as_int else "MISSION_ITEM"
    gcs.wait_for(lambda: len({m.seq for m in gcs.messages(name, mark)}) >= count, 1.0)
    gcs.send(mav.MAVLink_mission_ack_message(1, 1, 0, 0))
    return gcs.messages(name, mark)


@fuzz(examples=100)
@given(steps=st.lists(_mission_messages(), min_size=1, max_size=4), as_int=st.booleans())
def test_mission_protocol_keeps_a_valid_mission(fmu, steps, as_int):
    """Invariant: any sequence of MISSION_COUNT / ITEM / ITEM_INT / REQUEST / CLEAR_ALL / ACK /
    SET_CURRENT with any field values (NaN, infinity, huge) never makes a handler raise; the
    active mission is after each message either the one before it or a mission whose every
    item passes the item check; and a download of whatever is stored completes."""
    store = _store(fmu)
    marked = _mark(fmu)
    for msgs in steps:
        before = _snapshot(store)
        for m in msgs:
            fmu.gcs.send(m)
        fmu.gcs.step(0.02)
        assert _snapshot(store) == before or _valid(store)
    _healthy(fmu, marked)
    assert len(_download(fmu, as_int)) >= store.count


# -- commands --------------------------------------------------------------------------------

_COMMANDS = st.one_of(st.sampled_from([510, 511, 512, 519, 520, 20, 21, 22, 176, 179, 185, 192,
                                       300, 400]),
                      st.integers(0, 65535)).filter(lambda c: c != 246)  # reboot: the board


@st.composite
def _command(draw: Any) -> Any:
    cmd = draw(_COMMANDS)
    p = [draw(_F32) for _ in range(7)]
    if draw(st.booleans()):
        return mav.MAVLink_command_long_message(1, draw(st.sampled_from([0, 1])), cmd,
                                                draw(st.integers(0, 255)), *p)
    return mav.MAVLink_command_int_message(1, draw(st.sampled_from([0, 1])),
                                           draw(_FRAMES), cmd, 0, 0, *p[:4],
                                           draw(_LAT_E7), draw(_LON_E7), p[6])


@fuzz(examples=60)
@given(commands=st.lists(_command(), min_size=1, max_size=3, unique_by=lambda m: m.command))
def test_every_command_gets_one_ack(fmu, commands):
    """Invariant: COMMAND_LONG / COMMAND_INT with any command id and any parameters (NaN,
    infinity, huge) never make a handler raise, and each is answered by exactly one
    COMMAND_ACK (issue 21: even one no module here handles); a MAV_RESULT_FAILED from a
    handler that raised is a failure, not an ack."""
    gcs = fmu.gcs
    marked = _mark(fmu)
    mark = gcs.mark()
    for c in commands:
        gcs.send(c)
    gcs.step(0.15)
    _healthy(fmu, marked)
    acks = gcs.messages("COMMAND_ACK", mark)
    for c in commands:
        assert sum(1 for a in acks if a.command == c.command) == 1, (c, acks)
    gcs.command_long(400, [0.0, 21196.0])  # disarm (forced) whatever the commands did


# -- the MAVLink shell -----------------------------------------------------------------------

@fuzz(examples=120)
@given(chunks=st.lists(st.tuples(st.sampled_from([10, 10, 10, 0, 255]), st.integers(0, 255),
                                 st.integers(0, 255), st.binary(min_size=70, max_size=70)),
                       min_size=1, max_size=3))
def test_shell_survives_any_serial_control(fmu, chunks):
    """Invariant: SERIAL_CONTROL with any device, flags, count and bytes never makes a handler
    raise, and the shell still runs a line typed after them."""
    gcs = fmu.gcs
    marked = _mark(fmu)
    for device, flags, count, data in chunks:
        gcs.send(mav.MAVLink_serial_control_message(device, flags, 0, 0, count, list(data)))
    gcs.send(mav.MAVLink_serial_control_message(10, 6, 0, 0, 2, [3, 10] + [0] * 68))
    gcs.step(0.02)
    _healthy(fmu, marked)
    gcs._shell_open = False  # a fresh prompt: whatever the bytes left on the line is ended
    assert "fuzz-ok" in gcs.shell("echo fuzz-ok", timeout_s=1.0)
