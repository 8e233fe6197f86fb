"""Where the host time of the default flight goes, by component (a tool, not a figure).

Runs the flight in one process under cProfile and sums each function's own time by the part of
the tree it belongs to. ``python -m bench.profile_flight [--top N] [--save FILE]``.
"""

from __future__ import annotations

import argparse
import collections
import cProfile
import pstats
import tempfile

from hil.flight import FlightConfig, fly

PARTS = [
    "peripherals/mpu6000", "peripherals/st_spi", "peripherals/l3gd20", "peripherals/lsm303d",
    "peripherals/ms5611", "peripherals/hmc5883", "peripherals/ublox", "peripherals/errors",
    "peripherals/regs", "peripherals", "firmware/drivers/imu/mpu6000", "firmware/drivers/imu",
    "firmware/drivers/px4io", "firmware/drivers/gps", "firmware/drivers",
    "firmware/modules/logger", "firmware/modules/sensors", "firmware/modules/ekf2",
    "firmware/modules/mc_rate", "firmware/modules/mc_att", "firmware/modules/mc_pos",
    "firmware/modules/commander", "firmware/modules/navigator", "firmware/modules/mavlink",
    "firmware/modules/land", "firmware/modules/rc_update", "firmware/modules/battery",
    "firmware/modules", "firmware/platform/uorb", "firmware/platform/workqueue",
    "firmware/platform/hrt", "firmware/platform/perf", "firmware/platform", "ioproc/firmware",
    "ioproc/rc", "ioproc/mixer", "ioproc", "board/kernel", "board/spi", "board/gpio",
    "board/uart", "board/timer", "board/i2c", "board", "hil/world", "hil/rc", "hil/gcs", "hil",
    "pymavlink", "jsbsim"]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--top", type=int, default=40)
    ap.add_argument("--save", default=None, help="also save the raw cProfile stats here")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as out:
        prof = cProfile.Profile()
        summary = prof.runcall(fly, FlightConfig(out_dir=out, mode="local", progress=False,
                                                 plot=False))
    if args.save:
        prof.dump_stats(args.save)
    st = pstats.Stats(prof)
    agg: collections.Counter[str] = collections.Counter()
    for (fn, _line, name), (_cc, _nc, tt, _ct, _callers) in st.stats.items():  # type: ignore
        key = next((p for p in PARTS if p in fn), f"other: {name}")
        agg[key] += tt
    total = sum(agg.values())
    virtual = summary["phases"][-1]["t_s"]
    print(f"profiled {total:.1f} s of host time for {virtual:.1f} virtual s "
          f"({total / virtual * 1000:.0f} ms per virtual s under cProfile)")
    for key, value in agg.most_common(args.top):
        print(f"{value:8.2f} s {100 * value / total:5.1f} %  {key}")


if __name__ == "__main__":
    main()
