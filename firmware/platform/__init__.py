"""The flight-stack platform layer: what PX4's ``platforms/common`` gives modules.

One :class:`Platform` per board bundles the kernel, the high-resolution timer, the uORB broker,
the work queues and the perf counters. It is passed explicitly to every driver and module, so two
boards can live in one process without sharing any state.
"""

from __future__ import annotations

from firmware.platform.core import (SEV_DEBUG, SEV_EMERG, SEV_ERR, SEV_INFO, SEV_WARN,
                                    Platform)

__all__ = ["Platform", "SEV_EMERG", "SEV_ERR", "SEV_WARN", "SEV_INFO", "SEV_DEBUG"]
