"""Logger module: topics, parameters, console messages, dropouts and files, read back by pyulog."""

import shutil
from pathlib import Path

import numpy as np
import pytest

import firmware
from board.kernel import Kernel
from firmware.modules.logger import Logger, get_profile, log_path_for
from firmware.modules.logger.ulog import SYNC_MAGIC
from firmware.platform import Platform
from firmware.platform.msgdef import MessageRegistry, parse_msg

import pyulog  # noqa: E402 - a dependency of the package
from common.units import G0_M_S2

MS = 1_000_000  # ns


def make(tmp_path, **kw):
    k = Kernel("fmu")
    p = Platform(k)
    kw.setdefault("profile", {"sensor_accel": 0})
    lg = Logger(p, tmp_path / "log", **kw)
    return k, p, lg


def accel_publisher(k, p, period_ms=2, instances=1, until_ms=1000):
    """Publish sensor_accel with values derived from the time, on ``instances`` instances."""
    pubs = [p.orb.advertise_multi("sensor_accel") for _ in range(instances)]
    msg = p.orb.new("sensor_accel")
    sent = []

    def pub():
        t = p.time_us()
        for i, pb in enumerate(pubs):
            msg.timestamp = t
            msg.timestamp_sample = t - 100
            msg.device_id = 0x100 + i
            msg.x, msg.y, msg.z = t / 1e6, 0.1 * i, -G0_M_S2
            msg.clip_counter = [i, 0, t % 7]
            pb.publish(msg)
            sent.append((i, t))

    k.call_every(period_ms * MS, pub)
    return sent


def test_published_values_come_back_exactly(tmp_path):
    k, p, lg = make(tmp_path)
    sent = accel_publisher(k, p, period_ms=2)    # 500 Hz, logged at every update
    lg.start()
    k.run(1000 * MS)
    lg.stop()
    (path,) = lg.log_files
    assert path == tmp_path / "log" / "2024-01-01" / "00_00_00.ulg"
    u = pyulog.ULog(str(path))
    assert not u.file_corruption and not u.dropouts
    d = u.get_dataset("sensor_accel", 0).data
    ts = [t for _, t in sent]
    assert list(d["timestamp"]) == ts
    assert list(d["timestamp_sample"]) == [t - 100 for t in ts]
    np.testing.assert_array_equal(d["x"], (np.array(ts) / 1e6).astype(np.float32))
    assert set(d["z"]) == {np.float32(-G0_M_S2)}
    assert list(d["clip_counter[2]"]) == [t % 7 for t in ts]
    assert set(d["device_id"]) == {0x100}
    assert u.start_timestamp == 0


def test_multi_instance_topics_are_logged_with_their_multi_id(tmp_path):
    k, p, lg = make(tmp_path)
    accel_publisher(k, p, period_ms=10, instances=3, until_ms=500)
    lg.start()
    k.run(500 * MS)
    lg.stop()
    u = pyulog.ULog(str(lg.log_files[0]))
    series = sorted((d.multi_id, len(d.data["timestamp"]), set(d.data["device_id"]))
                    for d in u.data_list if d.name == "sensor_accel")
    assert series == [(0, 50, {0x100}), (1, 50, {0x101}), (2, 50, {0x102})]


def test_rate_limited_topics_follow_the_profile(tmp_path):
    k, p, lg = make(tmp_path, profile="default")
    accel_publisher(k, p, period_ms=1)    # 1 kHz, default profile logs sensor_accel at 50 Hz
    lg.start()
    k.run(2000 * MS)
    lg.stop()
    d = pyulog.ULog(str(lg.log_files[0])).get_dataset("sensor_accel").data
    assert 98 <= len(d["timestamp"]) <= 101
    gaps = np.diff(d["timestamp"])
    assert gaps.min() >= 16_000 and gaps.max() <= 24_000   # 20 ms +- one 3.5 ms poll


def test_profile_skips_unknown_topics_quietly(tmp_path):
    _k, p, lg = make(tmp_path, profile="default")
    names = [t.name for t in lg.topics]
    assert "sensor_accel" in names and "vehicle_command" in names
    assert lg.skipped and not set(lg.skipped) & set(p.orb.registry.topics)
    assert all(t.name in p.orb.registry.topics for t in lg.topics)
    assert [t.interval_us for t in get_profile({"a": 0, "b": 50})] == [0, 20_000]
    assert get_profile("default+sensors") and len({t.name for t in get_profile(
        "default+sensors")}) == len(get_profile("default+sensors"))
    with pytest.raises(ValueError, match="unknown logger profile"):
        get_profile("nope")


def test_parameters_at_start_and_their_changes(tmp_path):
    params = {"MC_ROLL_P": 6.5, "SYS_AUTOSTART": 4001, "COM_ARM_WO_GPS": 1}
    k, p, lg = make(tmp_path, params_provider=lambda: dict(params))
    upd = p.orb.advertise("parameter_update")
    msg = p.orb.new("parameter_update")

    def change():
        params["MC_ROLL_P"] = 7.25
        params["NEW_PARAM"] = 3
        msg.timestamp = p.time_us()
        msg.instance += 1
        upd.publish(msg)

    k.call_at(300 * MS, change)
    lg.start()
    k.run(600 * MS)
    lg.stop()
    u = pyulog.ULog(str(lg.log_files[0]))
    assert u.initial_parameters == {"MC_ROLL_P": 6.5, "SYS_AUTOSTART": 4001,
                                    "COM_ARM_WO_GPS": 1}
    assert [(name, v) for _, name, v in u.changed_parameters] == [("MC_ROLL_P", 7.25),
                                                                  ("NEW_PARAM", 3)]
    assert isinstance(u.initial_parameters["SYS_AUTOSTART"], int)


def test_console_messages_become_logged_strings_with_levels(tmp_path):
    k, p, lg = make(tmp_path)
    p.error("early", "before the log: not in it")
    lg.start()
    k.call_at(100 * MS, p.warn, "sensors", "baro timeout")
    k.call_at(200 * MS, p.error, "commander", "arming denied")
    k.call_at(300 * MS, p.info, "navigator", "mission ok")
    k.run(400 * MS)
    lg.stop()
    u = pyulog.ULog(str(lg.log_files[0]))
    got = [(m.log_level_str(), m.timestamp, m.message) for m in u.logged_messages]
    assert got == [("INFO", 0, "[logger] Opened full log file: 00_00_00.ulg"),
                   ("WARNING", 100_000, "[sensors] baro timeout"),
                   ("ERROR", 200_000, "[commander] arming denied"),
                   ("INFO", 300_000, "[navigator] mission ok")]


def test_slow_sd_card_causes_dropouts(tmp_path):
    k, p, lg = make(tmp_path, sd_write_rate_bytes_s=20_000, buffer_bytes=2048)
    sent = accel_publisher(k, p, period_ms=1)    # ~50 kB/s of sensor_accel
    lg.start()
    k.run(1000 * MS)
    lg.stop()
    u = pyulog.ULog(str(lg.log_files[0]))
    assert not u.file_corruption
    n = len(u.get_dataset("sensor_accel").data["timestamp"])
    assert 0 < n < len(sent) * 0.6
    assert len(u.dropouts) == lg.dropouts > 3
    assert sum(d.duration for d in u.dropouts) == lg.dropout_total_ms > 100
    assert lg.dropped_messages + n == len(sent)
    assert f"dropouts: {lg.dropouts} (total" in lg.status()


def test_fast_sd_card_has_no_dropouts_and_status_reports_the_file(tmp_path):
    k, p, lg = make(tmp_path, sd_write_rate_bytes_s=1_000_000)
    accel_publisher(k, p, period_ms=1)
    lg.start()
    k.run(300 * MS)
    text = lg.status()
    assert "00_00_00.ulg" in text and "dropouts: 0" in text and "mode boot" in text
    assert lg.wq.name == "wq:lp_default"
    lg.stop()
    assert "not logging" in lg.status()
    assert not pyulog.ULog(str(lg.log_files[0])).dropouts


def _run_once(root):
    k = Kernel("fmu")
    p = Platform(k)
    lg = Logger(p, root, profile="default", params_provider=lambda: {"A": 1, "B": 0.5},
                sd_write_rate_bytes_s=30_000, buffer_bytes=4096)
    accel_publisher(k, p, period_ms=1, instances=2)
    k.call_at(150 * MS, p.warn, "x", "hello")
    lg.start()
    k.run(1500 * MS)
    lg.stop()
    return lg.log_files[0].read_bytes()


def test_same_inputs_give_byte_identical_files(tmp_path):
    a = _run_once(tmp_path / "a")
    b = _run_once(tmp_path / "b")
    assert a == b and len(a) > 1000
    assert str(tmp_path).encode() not in a


def test_arm_mode_writes_one_file_per_arming_in_a_dated_folder(tmp_path):
    armed = {"v": False}
    epoch = 1_719_791_990   # 2024-06-30T23:59:50Z: the second file falls on the next day
    k, p, lg = make(tmp_path, mode="arm", is_armed=lambda: armed["v"], utc_epoch_s=epoch)
    accel_publisher(k, p, period_ms=10)

    def set_armed(v):
        armed["v"] = v

    for t_ms, v in ((1000, True), (2000, False), (12_500, True), (13_000, False)):
        k.call_at(t_ms * MS, set_armed, v)
    lg.start()
    k.run(500 * MS)
    assert not lg.logging and "waiting for arming" in lg.status()
    k.run(14_000 * MS)
    lg.stop()
    root = tmp_path / "log"
    assert lg.log_files == [root / "2024-06-30" / "23_59_51.ulg",
                            root / "2024-07-01" / "00_00_02.ulg"]
    spans = []
    for path in lg.log_files:
        u = pyulog.ULog(str(path))
        ts = u.get_dataset("sensor_accel").data["timestamp"]
        spans.append((u.start_timestamp // 1000, int(ts[0]) // 1000, int(ts[-1]) // 1000))
    # arming is seen at the next 3.5 ms poll; the latest sample comes with the new file
    assert 1000 <= spans[0][0] <= 1004 and 990 <= spans[0][1] <= 1000
    assert 1990 <= spans[0][2] <= 2004
    assert 12_500 <= spans[1][0] <= 12_504 and 12_490 <= spans[1][1] and spans[1][2] <= 13_004


def test_bad_mode_is_refused(tmp_path):
    # (mode "arm" without is_armed follows vehicle_status, which exists: see the next tests)
    with pytest.raises(ValueError, match="mode"):
        make(tmp_path, mode="always")


def test_log_path_from_emulated_utc(tmp_path):
    assert log_path_for(tmp_path, 1_704_067_200_000_000 + 3_723_000_000) == \
        tmp_path / "2024-01-01" / "01_02_03.ulg"


def test_arm_mode_follows_vehicle_status_when_the_topic_exists(tmp_path):
    msg_dir = tmp_path / "msg"
    shutil.copytree(Path(firmware.__file__).parent / "msg", msg_dir)
    (msg_dir / "vehicle_status.msg").write_text(
        "uint64 timestamp\nuint8 arming_state\nuint8 ARMING_STATE_ARMED = 2\n")
    k = Kernel("fmu")
    p = Platform(k, MessageRegistry.from_dir(msg_dir))
    lg = Logger(p, tmp_path / "log", profile={"vehicle_status": 0}, mode="arm")
    pub = p.orb.advertise("vehicle_status")
    st = p.orb.new("vehicle_status")

    def set_state(state):
        st.timestamp = p.time_us()
        st.arming_state = state
        pub.publish(st)

    for t_ms, state in ((100, 1), (200, 2), (300, 1), (400, 2), (500, 1)):
        k.call_at(t_ms * MS, set_state, state)
    lg.start()
    k.run(600 * MS)
    lg.stop()
    assert len(lg.log_files) == 2
    for path, t_us in zip(lg.log_files, (200_000, 400_000)):
        d = pyulog.ULog(str(path)).get_dataset("vehicle_status").data
        assert list(d["arming_state"]) == [2, 1] and d["timestamp"][0] == t_us
        assert path.read_bytes().count(SYNC_MAGIC) == 0   # shorter than the 1 s sync period


def test_sync_messages_are_written_every_second(tmp_path):
    k, p, lg = make(tmp_path)
    accel_publisher(k, p, period_ms=50)
    lg.start()
    k.run(3100 * MS)
    lg.stop()
    assert lg.log_files[0].read_bytes().count(SYNC_MAGIC) == 3


def test_a_topic_without_leading_timestamp_is_skipped_with_a_warning(tmp_path):
    reg = MessageRegistry()
    reg.add(parse_msg("uint32 a\nuint64 timestamp\n", "odd"))
    reg.add(parse_msg("uint64 timestamp\nuint8 severity\nchar[127] text\n", "log_message"))
    reg.build()
    p = Platform(Kernel("fmu"), reg)
    lg = Logger(p, tmp_path, profile={"odd": 0})
    assert lg.topics == [] and lg.skipped == ["odd"]
    assert "not logging odd" in p.dmesg_text()
