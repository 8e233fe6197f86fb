"""``hil log info`` / ``hil log plot``: our own logs and real PX4 logs from the fixtures."""

import io
import math
from pathlib import Path

import pytest

from board.kernel import Kernel
from firmware.modules.logger import Logger
from firmware.platform import Platform
from hil.log_tools import info_main, plot_main


FIXTURES = Path("/work/shared/fixtures/ulog")
MS = 1_000_000


@pytest.fixture(scope="module")
def our_log(tmp_path_factory):
    """A 1 s log with attitude (a slow roll), two gyros, actuator outputs and a warning."""
    root = tmp_path_factory.mktemp("sd")
    k = Kernel("fmu")
    p = Platform(k)
    lg = Logger(p, root, profile="default", params_provider=lambda: {"MC_ROLL_P": 6.5})
    att = p.orb.advertise("vehicle_attitude")
    gyros = [p.orb.advertise_multi("sensor_gyro") for _ in range(2)]
    outs = p.orb.advertise("actuator_outputs")
    a, g, o = p.orb.new("vehicle_attitude"), p.orb.new("sensor_gyro"), p.orb.new("actuator_outputs")

    def pub():
        t = p.time_us()
        roll = 0.5 * t / 1e6
        a.timestamp = g.timestamp = o.timestamp = t
        a.q = [math.cos(roll / 2), math.sin(roll / 2), 0.0, 0.0]
        att.publish(a)
        g.x = 0.5
        for pub_ in gyros:
            pub_.publish(g)
        o.noutputs = 4
        o.output[:4] = [1000 + t / 1000, 1100, 1200, 1300]
        outs.publish(o)

    k.call_every(4 * MS, pub)
    k.call_at(500 * MS, p.warn, "commander", "low battery")
    lg.start()
    k.run(1000 * MS)
    lg.stop()
    return lg.log_files[0]


def test_info_on_our_log_lists_topics_info_and_messages(our_log):
    out = io.StringIO()
    assert info_main(our_log, out=out) == 0
    text = out.getvalue()
    assert "ULog format version: 1" in text and "No Dropouts" in text
    assert " ver_hw: PX4_FMU_V2" in text and "Parameters: 1 " in text
    for line in (" vehicle_attitude (0, 49)", " sensor_gyro (0, 44)", " sensor_gyro (1, 44)",
                 " actuator_outputs (0, 76)"):
        assert line in text
    assert "WARN   [commander] low battery" in text


@pytest.mark.parametrize("name", ["sample.ulg", "sample_log_small.ulg",
                                  "sample_appended_multiple.ulg", "sample_px4_events.ulg"])
def test_info_survives_real_px4_logs(name):
    path = FIXTURES / name
    if not path.exists():
        raise AssertionError("fixture logs missing: ../shared/fixtures/ulog")
    out = io.StringIO()
    assert info_main(path, out=out) == 0
    assert "Name (multi id, message size in bytes)" in out.getvalue()


def test_info_on_sample_matches_known_facts():
    path = FIXTURES / "sample.ulg"
    if not path.exists():
        raise AssertionError("fixture logs missing: ../shared/fixtures/ulog")
    out = io.StringIO()
    info_main(path, out=out)
    text = out.getvalue()
    assert "ULog format version: 0" in text
    assert "Dropouts: count: 4, total duration: 0.1 s, max: 62 ms, mean: 29 ms" in text
    assert "Parameters: 493 (6 change(s) during the log)" in text
    line = next(x for x in text.splitlines() if x.startswith(" sensor_combined (0, 72)"))
    assert line.split()[-2:] == ["17070", "1229040"]
    assert text.count("ERROR  [sensors] no barometer found on /dev/baro0 (2)") == 4


def test_info_rejects_what_is_not_a_ulog(tmp_path):
    bad = tmp_path / "x.ulg"
    bad.write_bytes(b"not a log at all")
    err = io.StringIO()
    assert info_main(bad, out=io.StringIO(), err=err) == 1
    assert "not a ULog file" in err.getvalue()
    assert info_main(tmp_path / "missing.ulg", out=io.StringIO(), err=io.StringIO()) == 1


def test_plot_writes_pngs_and_skips_missing_topics(our_log, tmp_path):
    out = io.StringIO()
    rc = plot_main(our_log, ["sensor_gyro", "no_such_topic"], tmp_path / "plots", out=out)
    assert rc == 0
    stem = our_log.stem
    for name in ("attitude", "rates", "actuators", "sensor_gyro"):
        png = tmp_path / "plots" / f"{stem}_{name}.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
    text = out.getvalue()
    assert "no position plot" in text and "topic no_such_topic is not in the log" in text
    assert not (tmp_path / "plots" / f"{stem}_position.png").exists()


def test_plot_fails_cleanly_on_a_bad_file(tmp_path):
    bad = tmp_path / "x.ulg"
    bad.write_bytes(b"ULog")
    assert plot_main(bad, [], tmp_path, out=io.StringIO(), err=io.StringIO()) == 1
