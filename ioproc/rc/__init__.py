"""RC receiver decoders of the IO coprocessor and the :class:`RcInput` multiplexer.

Each decoder is fed bytes (S.BUS, DSM, SUMD, ST24) or capture edges (PPM) stamped with the
caller's virtual time and reports PX4-scaled µs channel values, flags and counters; see
``ioproc/rc/common.py`` for the shared state every decoder exposes.
"""

from ioproc.rc.common import IO_MAX_CHANNELS, RcDecoder
from ioproc.rc.dsm import DsmDecoder, encode_dsm_frame
from ioproc.rc.input import DSM, PPM, RC_LOST_US, SBUS, ST24, SUMD, RcInput
from ioproc.rc.ppm import PpmDecoder, ppm_edges
from ioproc.rc.sbus import SbusDecoder, encode_sbus_frame
from ioproc.rc.st24 import St24Decoder, encode_st24_frame
from ioproc.rc.sumd import SumdDecoder, encode_sumd_frame

__all__ = [
    "DSM", "IO_MAX_CHANNELS", "PPM", "RC_LOST_US", "SBUS", "ST24", "SUMD",
    "DsmDecoder", "PpmDecoder", "RcDecoder", "RcInput", "SbusDecoder", "St24Decoder",
    "SumdDecoder", "encode_dsm_frame", "encode_sbus_frame", "encode_st24_frame",
    "encode_sumd_frame", "ppm_edges",
]
