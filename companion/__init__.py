"""The companion computer: a Linux board (a Raspberry Pi 4 class computer) wired to the FMU's
TELEM2, running the same firmware platform (uORB, work queues, HRT, parameters, perf, nsh) in
lockstep virtual time as a third board process (docs/companion.md)."""
