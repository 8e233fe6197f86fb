"""QGroundControl's MAVLink console (SERIAL_CONTROL) and log download from the SD card."""

import calendar

from pymavlink.dialects.v20 import common as mav


def test_mavlink_shell_runs_ver_all(session):
    out = session.gcs.shell("ver all")
    assert "HW arch: PX4_FMU_V2" in out
    assert "FW version" in out
    assert "nsh>" not in out and "ver all" not in out.splitlines()[0:1]


def test_mavlink_shell_keeps_going_after_errors(session):
    gcs = session.gcs
    assert "command not found" in gcs.shell("no_such_command")
    assert "mavlink: running" in gcs.shell("mavlink status")
    replies = gcs.messages("SERIAL_CONTROL")
    assert all(m.flags & mav.SERIAL_CONTROL_FLAG_REPLY and m.count <= 70 for m in replies)


def test_log_list_and_download_byte_identical(session):
    gcs = session.gcs
    session.shell("param set SDLOG_MODE 1")  # log from start, not from arming
    session.orch.call("fmu", "shell", "logger stop")
    session.shell("logger start")
    gcs.step(0.5)
    session.shell("logger stop")  # the file must not grow while we compare
    log_root = session.root / "sd" / "log"
    extra = log_root / "2024-05-06" / "07_08_09.ulg"
    extra.parent.mkdir(parents=True, exist_ok=True)
    extra.write_bytes(bytes(range(256)) * 13 + b"tail")  # not a multiple of 90 bytes
    files = sorted(log_root.rglob("*.ulg"))
    assert len(files) >= 2
    entries = gcs.log_list()
    assert [e.size for e in entries] == [f.stat().st_size for f in files]
    assert entries[0].num_logs == len(files)
    e_extra = entries[files.index(extra)]
    assert e_extra.time_utc == calendar.timegm((2024, 5, 6, 7, 8, 9, 0, 0, 0))
    for entry, path in zip(entries, files):
        data = gcs.log_download(entry.id, entry.size, timeout_s=30.0)
        assert data == path.read_bytes(), path


def test_log_request_end_stops_the_transfer(session):
    gcs = session.gcs
    entries = gcs.log_list()
    big = max(entries, key=lambda e: e.size)
    mark = gcs.mark()
    gcs.send(mav.MAVLink_log_request_data_message(1, 1, big.id, 0, 0xFFFFFFFF))
    gcs.wait_message("LOG_DATA", since=mark)
    gcs.send(mav.MAVLink_log_request_end_message(1, 1))
    gcs.step(0.05)
    n = len(gcs.messages("LOG_DATA", mark))
    gcs.step(0.3)
    assert len(gcs.messages("LOG_DATA", mark)) == n


def test_mavlink_shell_line_is_bounded_and_decodes_utf8(session):
    """Review of defect 2: the MAVLink shell kept every byte without a line end (a client
    could grow the FMU's memory without bound) and decoded it as latin-1, so "é" typed in
    QGroundControl's console reached the shell as "Ã©". It now shares the console's line
    editor: at most LINE_BYTES kept (the shell refuses the cut line as too long) and UTF-8."""
    from firmware.shell.line_editor import LINE_BYTES

    gcs = session.gcs
    shell = session.udp_instance().shell
    assert gcs.shell("echo h\u00e9") == "h\u00e9\n"
    gcs._serial_send(b"x" * (3 * LINE_BYTES))   # no line end
    gcs.step(0.05)
    assert len(shell.editor.line) <= LINE_BYTES
    assert "too long" in gcs.shell("")
    assert gcs.shell("echo ok") == "ok\n"
