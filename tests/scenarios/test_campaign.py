"""Campaigns: scenario x seed x parameter runs in local processes and on a Dask LocalCluster
give the same verdicts, and the report says how to reproduce each failure."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hil.campaign import expand, parse_seeds, run_campaign, write_report
from hil.scenarios import LIBRARY

pytestmark = pytest.mark.slow
QUICK = [str(LIBRARY / "imu_noise.yaml"), str(LIBRARY / "rc_frame_loss_burst.yaml")]


def test_seeds_and_expansion():
    assert parse_seeds("1-3,7,2") == [1, 2, 3, 7]
    with pytest.raises(ValueError, match="--seeds"):
        parse_seeds("3-1")
    runs = expand(["a.yaml"], [1, 2], {"X": [1, 2], "Y": [0.5]})
    assert [(r.seed, r.params) for r in runs] == [
        (1, (("X", 1), ("Y", 0.5))), (1, (("X", 2), ("Y", 0.5))),
        (2, (("X", 1), ("Y", 0.5))), (2, (("X", 2), ("Y", 0.5)))]


def _verdicts(results):
    return [(r["name"], r["seed"], r["passed"],
             [(e["text"], e["verdict"], e["t_met_s"]) for e in r["expectations"]])
            for r in results]


def test_local_and_dask_campaigns_agree(tmp_path):
    runs = expand(QUICK, [1, 2])
    local = run_campaign(runs, str(tmp_path / "local"), jobs=2, one_process=True,
                         progress=None)
    dask = run_campaign(runs, str(tmp_path / "dask"), jobs=2, dask="local", progress=None)
    assert len(local) == 4 and all(r["passed"] for r in local), local
    assert _verdicts(local) == _verdicts(dask)
    md, js = write_report(local, str(tmp_path / "local"))
    report = json.loads(Path(js).read_text())
    assert report["summary"] == {**report["summary"], "runs": 4, "passed": 4, "failed": 0}
    assert "imu_noise" in Path(md).read_text()


def test_a_failing_run_is_reported_with_the_command_that_reproduces_it(tmp_path):
    # IMU failover cannot happen within 1 ms: the run fails, the report shows how to rerun it.
    src = Path(QUICK[0]).read_text().replace("within: 0.3", "within: 0.001")
    sc = tmp_path / "imu_noise_strict.yaml"
    sc.write_text(src.replace("name: imu_noise", "name: imu_noise_strict"))
    res = run_campaign(expand([str(sc)], [3]), str(tmp_path / "c"), jobs=1,
                       one_process=True, progress=None)
    assert not res[0]["passed"]
    md, _ = write_report(res, str(tmp_path / "c"))
    text = Path(md).read_text()
    assert f"hil scenario {sc} --seed 3" in text and "--one-process" in text
