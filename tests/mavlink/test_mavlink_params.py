"""The parameter protocol against the board's own Params: list, hash, set, read, persistence."""

import struct
import zlib

import pytest
from pymavlink.dialects.v20 import common as mav

from firmware.modules.mavlink.params import crc32_px4
from tests.mavlink.conftest import open_session


def _px4_hash(names, values, types):
    crc = 0
    for n in names:
        crc = crc32_px4(n.encode(), crc)
        fmt = "<i" if types[n] == "INT32" else "<f"
        crc = crc32_px4(struct.pack(fmt, values[n]), crc)
    return crc


def test_crc32_px4_is_crc32_without_inversion():
    data = b"SYS_AUTOSTART\xa1\x0f\x00\x00"
    assert crc32_px4(data) == (~zlib.crc32(data, 0xFFFFFFFF)) & 0xFFFFFFFF


def test_param_list_equals_board_params_hash_first(session):
    gcs = session.gcs
    got = gcs.param_list()
    board = session.orch.handles["fmu"].endpoint.board.system.params
    assert list(got) == board.names
    for name, v in got.items():
        assert v == board.values[name], name
        assert type(v) is (int if board.defs[name].type == "INT32" else float), name
    assert gcs.param_order[0] == "_HASH_CHECK"
    first = gcs.messages("PARAM_VALUE")[0]
    assert first.param_type == mav.MAV_PARAM_TYPE_UINT32 and first.param_index == 65535
    types = {n: board.defs[n].type for n in board.names}
    assert gcs.param_hash == _px4_hash(board.names, board.values, types)
    pv = [m for m in gcs.messages("PARAM_VALUE") if gcs.param_name(m) == "SYS_AUTOSTART"][-1]
    assert pv.param_type == mav.MAV_PARAM_TYPE_INT32 and pv.param_count == len(board.names)
    assert pv.param_index == board.names.index("SYS_AUTOSTART")


def test_int_param_travels_bytewise(session):
    gcs = session.gcs
    assert gcs.param_set("SDLOG_UTC_OFFSET", -5) == -5
    pv = gcs.last["PARAM_VALUE"]
    assert gcs.raw_float_bytes(pv) == struct.pack("<i", -5)  # not the float -5.0
    assert gcs.param_get("SDLOG_UTC_OFFSET") == -5
    by_index = gcs.messages("PARAM_VALUE")[-1].param_index
    mark = gcs.mark()
    gcs.send(mav.MAVLink_param_request_read_message(1, 1, b"", by_index))
    m = gcs.wait_message("PARAM_VALUE", since=mark)
    assert gcs.param_name(m) == "SDLOG_UTC_OFFSET"


def test_unknown_param_answered_with_statustext(session):
    gcs = session.gcs
    mark = gcs.mark()
    gcs.send(mav.MAVLink_param_set_message(1, 1, b"NO_SUCH_PARAM", 1.0,
                                           mav.MAV_PARAM_TYPE_REAL32))
    st = gcs.wait_message("STATUSTEXT", lambda m: b"unknown param" in bytes(m.text, "latin-1")
                          if isinstance(m.text, str) else b"unknown param" in m.text,
                          since=mark)
    assert "NO_SUCH_PARAM" in (st.text if isinstance(st.text, str) else st.text.decode())


def test_hash_check_set_stops_the_list(session):
    gcs = session.gcs
    mark = gcs.mark()
    gcs.send(mav.MAVLink_param_request_list_message(1, 1))
    gcs.wait_message("PARAM_VALUE", since=mark)
    gcs.send(mav.MAVLink_param_set_message(1, 1, b"_HASH_CHECK", 0.0, mav.MAV_PARAM_TYPE_UINT32))
    gcs.step(1.0)
    n = len(gcs.messages("PARAM_VALUE", mark))
    total = len(session.orch.handles["fmu"].endpoint.board.system.params.names)
    assert 1 <= n < total  # the first batches went out, then the stream stopped


@pytest.mark.parametrize("name,value", [("SDLOG_PROFILE", 3)])
def test_set_survives_reboot_through_fram(tmp_path, name, value):
    s = open_session(tmp_path)
    try:
        s.gcs.wait_heartbeat()
        assert s.gcs.param_set(name, value) == value
        s.gcs.step(0.5)  # the autosave after 300 ms writes FRAM
    finally:
        s.close()
    s2 = open_session(tmp_path)  # a new board on the same FRAM file
    try:
        s2.gcs.wait_heartbeat()
        assert s2.gcs.param_get(name) == value
    finally:
        s2.close()
