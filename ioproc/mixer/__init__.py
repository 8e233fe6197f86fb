"""PX4 mixer library as run by the E14 IO: text parser, null/simple/multirotor mixers, group,
and the page-52 upload protocol."""

from ioproc.mixer.base import (
                               ControlSource,
                               Mixer,
                               NullMixer,
                               Scaler,
                               SimpleInput,
                               SimpleMixer,
                               zero_source,
)
from ioproc.mixer.group import MixerGroup
from ioproc.mixer.multirotor import GEOMETRIES, ROTOR_TABLES, MultirotorMixer
from ioproc.mixer.parser import (
                               MixerParseError,
                               MixerRefusal,
                               filter_mixer_file,
                               load_from_buf,
                               parse_mixer_text,
)
from ioproc.mixer.upload import ChunkResult, MixerUpload, encode_mixer_upload

__all__ = [
                               "GEOMETRIES",
                               "ROTOR_TABLES",
                               "ChunkResult",
                               "ControlSource",
                               "Mixer",
                               "MixerGroup",
                               "MixerParseError",
                               "MixerRefusal",
                               "MixerUpload",
                               "MultirotorMixer",
                               "NullMixer",
                               "Scaler",
                               "SimpleInput",
                               "SimpleMixer",
                               "encode_mixer_upload",
                               "filter_mixer_file",
                               "load_from_buf",
                               "parse_mixer_text",
                               "zero_source",
]
