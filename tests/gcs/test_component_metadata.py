"""COMPONENT_METADATA / COMPONENT_INFORMATION and the metadata files over MAVLink FTP, as
QGroundControl fetches them: the request with pymavlink (firmware dialect), then the general
file and the parameter metadata downloaded with pymavlink's MAVFTP (virtual clock)."""

import json
import lzma

import pytest

from firmware.modules.mavlink.ftp import crc32_px4
from tests.gcs.helpers import use_dialect
from tests.mavlink.conftest import open_session
from tests.mavlink.ftp_client import ftp_client

mav = None


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    global mav
    s = open_session(tmp_path_factory.mktemp("metadata"))
    mav = use_dialect(s.gcs)
    s.gcs.wait_heartbeat()
    yield s
    s.close()


@pytest.fixture
def client(session, monkeypatch):
    return ftp_client(session, monkeypatch)


def _request(gcs, msg_id, name):
    mark = gcs.mark()
    ack = gcs.command_long(mav.MAV_CMD_REQUEST_MESSAGE, [msg_id])
    assert ack.result == mav.MAV_RESULT_ACCEPTED
    return gcs.wait_message(name, since=mark)


def test_metadata_message_names_the_general_file_and_its_crc(session, client):
    gcs = session.gcs
    meta = _request(gcs, mav.MAVLINK_MSG_ID_COMPONENT_METADATA, "COMPONENT_METADATA")
    assert meta.uri == "mftp://etc/extras/component_general.json.xz"
    assert 0 < meta.time_boot_ms <= session.dmesg_mark() // 1000
    info = _request(gcs, mav.MAVLINK_MSG_ID_COMPONENT_INFORMATION, "COMPONENT_INFORMATION")
    assert info.general_metadata_uri == meta.uri
    assert info.general_metadata_file_crc == meta.file_crc and info.peripherals_metadata_uri == ""

    path = meta.uri[len("mftp://"):]
    packed = client.read(path, 1 << 20)
    general_raw = lzma.decompress(packed)
    assert crc32_px4(general_raw) == meta.file_crc
    assert client.read(path[:-3], 1 << 20) == general_raw        # also served plain
    general = json.loads(general_raw)
    assert general["version"] == 1
    (ptype,) = general["metadataTypes"]
    assert ptype["type"] == mav.COMP_METADATA_TYPE_PARAMETER
    assert ptype["uri"] == "mftp://etc/extras/parameters.json.xz"

    params_raw = lzma.decompress(client.read(ptype["uri"][len("mftp://"):], 1 << 22))
    assert crc32_px4(params_raw) == ptype["fileCrc"]
    doc = json.loads(params_raw)
    assert doc["version"] == 1 and doc["scope"] == "Firmware"
    by_name = {p["name"]: p for p in doc["parameters"]}
    defs = session.orch.handles["fmu"].endpoint.board.system.params.defs
    assert sorted(by_name) == sorted(defs)                        # every declared parameter
    vel = by_name["MPC_XY_VEL_MAX"]
    d = defs["MPC_XY_VEL_MAX"]
    assert vel["type"] == "Float" and vel["units"] == d.unit == "m/s"
    assert (vel["min"], vel["max"]) == pytest.approx((d.min, d.max))
    assert vel["default"] == pytest.approx(d.default) and vel["shortDesc"] == d.short
    sysid = by_name["MAV_SYS_ID"]
    assert sysid["type"] == "Int32" and sysid["default"] == 1
    assert (sysid["min"], sysid["max"]) == (defs["MAV_SYS_ID"].min, defs["MAV_SYS_ID"].max)
    assert sysid.get("rebootRequired") == (defs["MAV_SYS_ID"].reboot_required or None)
    enum = next(p for n, p in by_name.items() if defs[n].values)
    assert {v["value"]: v["description"] for v in enum["values"]} == defs[enum["name"]].values
    assert any("decimalPlaces" in p for p in doc["parameters"])


def test_extras_folder_lists_and_is_read_only(session, client):
    from pymavlink import mavftp

    ret = client.cmd_list(["/etc/extras"])
    assert ret.error_code == mavftp.FtpError.Success
    names = {e.name for e in ret.directory_listing}
    assert names == {"component_general.json", "component_general.json.xz",
                     "parameters.json", "parameters.json.xz"}
    assert client.cmd_rm(["/etc/extras/parameters.json"]).error_code != \
        mavftp.FtpError.Success
    assert client.cmd_list(["/etc/extras/nope.json"]).error_code != mavftp.FtpError.Success
