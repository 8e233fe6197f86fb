"""The real-time factor of the default flight (``hil run``): both board processes, the world,
the GCS, the whole mission. One run (it takes a minute or more); the figure is the run's RTF."""

from __future__ import annotations

import tempfile

from hil.flight import FlightConfig, fly


def bench_flight_rtf() -> float:
    with tempfile.TemporaryDirectory() as out:
        summary = fly(FlightConfig(out_dir=out, progress=False, plot=False))
    return float(summary["rtf"])


if __name__ == "__main__":
    print(f"flight_rtf: {bench_flight_rtf():.2f}")
