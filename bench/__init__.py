"""Benchmarks: each figure is a function returning a number, registered in FIGURES.

``hil bench`` runs them and prints a table (or, with ``--json``, one JSON object with one key per
figure). Each function returns the median of several runs itself. Benchmarks may read the wall
clock; tests never assert on speed.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Figure:
    key: str
    target: str       # "module:function" inside the bench package
    unit: str
    about: str
    issue: int        # the issue that introduced the figure


FIGURES: list[Figure] = [
    Figure("kernel_events_per_s", "bench_kernel:bench_kernel_events_per_s", "events/s",
           "kernel events (self-rescheduling callbacks on 16 timers)", 2),
    Figure("uorb_publish_callback_per_s", "bench_uorb:bench_uorb_publish_callback_per_s",
           "publishes/s", "uORB publish -> callback subscription -> work item run -> update()", 2),
    Figure("spi_14byte_transfers_per_s", "bench_spi:bench_spi_14byte_transfers_per_s",
           "transfers/s", "14-byte SPI burst reads from a register-file target", 2),
    Figure("uart_bytes_per_s", "bench_uart:bench_uart_bytes_per_s", "bytes/s",
           "bytes through a UART pair at 1.5 Mbaud in 68-byte bursts (IDLE + read)", 2),
    Figure("uart_mismatch_frames_per_s", "bench_uart_mismatch:bench_uart_mismatch_frames_per_s",
           "frames/s", "bit-level decoding of a UART heard at the wrong baud (GPS baud scan)", 4),
    Figure("lockstep_overhead_us_per_quantum",
           "bench_lockstep:bench_lockstep_overhead_us_per_quantum", "us/quantum",
           "orchestrator + two board processes with a 1 kHz tick (every quantum exchanged)", 3),
    Figure("rtf_world_two_empty_boards", "bench_lockstep:bench_rtf_world_two_empty_boards",
           "x real time", "JSBSim F450 world + two empty board processes, 1 ms quantum", 3),
    Figure("rtf_world_two_ticking_boards", "bench_lockstep:bench_rtf_world_two_ticking_boards",
           "x real time", "as above, boards with a 1 kHz tick (no exchange skipped)", 3),
    Figure("rtf_jsbsim_only", "bench_world:bench_rtf_jsbsim_only", "x real time",
           "the F450 world alone at 1 kHz (reference for the figure above)", 3),
    Figure("sbus_frames_decoded_per_s", "bench_rc:bench_sbus_frames_decoded_per_s", "frames/s",
           "S.BUS frames fed byte by byte with timestamps into the IO's decoder", 5),
    Figure("px4io_transactions_per_s", "bench_px4io:bench_px4io_transactions_per_s",
           "transactions/s", "FMU encode + IO request handler + FMU decode, typical mix", 5),
    Figure("fmu_sensors_rtf", "bench_fmu_sensors:bench_fmu_sensors_rtf", "x real time",
           "the FMU with its six sensor drivers only, spinning on the turntable", 4),
    Figure("flight_rtf", "bench_flight:bench_flight_rtf", "x real time",
           "the default flight (hil run): two board processes, world, GCS, whole mission", 7),
    Figure("flight_rtf_over_jsbsim", "bench_flight:bench_flight_rtf_over_jsbsim", "ratio",
           "flight_rtf over JSBSim's F450 alone, same run: comparable across machines", 20),
    Figure("flight_rtf_fw", "bench_flight:bench_flight_rtf_fw", "x real time",
           "the standard plane's default mission (hil run --airframe plane)", 23),
    Figure("flight_rtf_vtol", "bench_flight:bench_flight_rtf_vtol", "x real time",
           "the standard VTOL's default mission (hil run --airframe vtol)", 23),
    Figure("mpu6000_sample_us", "bench_mpu6000:bench_mpu6000_sample_us", "us/sample",
           "host cost of one MPU6000 sample end to end (model, DRDY, SPI, driver, publish)", 4),
]
