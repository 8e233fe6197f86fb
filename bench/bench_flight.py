"""The real-time factor of the default flight (``hil run``): both board processes, the world,
the GCS, the whole mission. One run (it takes a minute or more); the figure is the run's RTF.

``flight_rtf_over_jsbsim`` divides that figure by the speed of the JSBSim F450 world alone
(:func:`bench.bench_world.bench_rtf_jsbsim_only`), measured in the same process right after the
flight. Both move together with the machine's speed, so the ratio says how much of the
machine's pace the emulated boards cost, in a figure comparable across machines. The flight is
flown once per process and shared by both figures. ``flight_rtf_fw`` is the same for the
standard plane's default mission (a longer flight: about five virtual minutes), and
``flight_rtf_vtol`` for the standard VTOL's (hover, both transitions and the plane's square).
"""

from __future__ import annotations

import functools
import tempfile

from bench.bench_world import bench_rtf_jsbsim_only
from hil.flight import FlightConfig, fly


@functools.cache
def _flight_rtf(airframe: int = 4011) -> float:
    with tempfile.TemporaryDirectory() as out:
        summary = fly(FlightConfig(out_dir=out, airframe=airframe, progress=False, plot=False))
    return float(summary["rtf"])


def bench_flight_rtf_fw() -> float:
    """The standard plane's default mission (SYS_AUTOSTART 2100), as ``hil run --airframe
    plane`` flies it."""
    return _flight_rtf(2100)


def bench_flight_rtf_vtol() -> float:
    """The standard VTOL's default mission (SYS_AUTOSTART 13000), as ``hil run --airframe
    vtol`` flies it."""
    return _flight_rtf(13000)


def bench_flight_rtf() -> float:
    return _flight_rtf()


def bench_flight_rtf_over_jsbsim() -> float:
    """The default flight's real-time factor over JSBSim's alone on the same model."""
    flight = _flight_rtf()
    return flight / bench_rtf_jsbsim_only()


if __name__ == "__main__":
    print(f"flight_rtf: {bench_flight_rtf():.2f}")
    print(f"flight_rtf_over_jsbsim: {bench_flight_rtf_over_jsbsim():.4f}")
