"""The IO's side of the mixer upload through page 52 (MIXERLOAD), E14 rules.

Payload of each WRITE to page 52 (offset ignored), as bytes of the LE register words:
``magic 0x6D74`` (bytes 74 6D), ``action`` (0 = reset, 1 = append), then mixer text, padded with
a NUL to an even length. The FMU sends 59-byte text chunks, then a chunk holding "\\n"
(io-and-rc.md §2.11). The IO appends each chunk to a 256-byte buffer and parses it at once;
MIXER_OK means "the whole buffer parsed with nothing left over". Unparseable text stays in the
buffer, so a parse error shows up as MIXER_OK staying clear (and, here, as ``last_error``).
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Final

from ioproc.mixer.group import MixerGroup
from ioproc.mixer.parser import MixerRefusal, load_from_buf
from ioproc.protocol import ERA, Era

F2I_MIXER_MAGIC: Final = 0x6D74
ACTION_RESET: Final = 0
ACTION_APPEND: Final = 1
HEADER_SIZE: Final = 3  #: uint16 magic + uint8 action (packed)
#: IO text buffer size per era.
TEXT_BUFFER_SIZE: Final[dict[Era, int]] = {Era.E14: 256}


@dataclass(frozen=True)
class ChunkResult:
    """What one chunk did. ``mixer_ok``: new MIXER_OK state; ``parsed``: failsafe recompute."""

    mixer_ok: bool | None  # None = chunk ignored, flag untouched
    parsed: bool


def encode_mixer_upload(text: str, max_transfer: int = 64) -> list[list[int]]:
    """FMU side (px4io mixer_send): register lists, one WRITE to page 52 each, last = "\\n"."""
    data = text.encode("latin-1")
    max_text = max_transfer - 2 - HEADER_SIZE
    writes, action, pos = [], ACTION_RESET, 0
    while pos < len(data):
        chunk = struct.pack("<HB", F2I_MIXER_MAGIC, action) + data[pos:pos + max_text]
        pos += max_text
        if len(chunk) % 2:
            chunk += b"\0"
        writes.append(list(struct.unpack(f"<{len(chunk) // 2}H", chunk)))
        action = ACTION_APPEND
    closing = struct.pack("<HB", F2I_MIXER_MAGIC, action) + b"\n"
    writes.append(list(struct.unpack("<2H", closing)))
    return writes


class MixerUpload:
    """Text buffer + loaded mixer group of the IO (mixer_handle_text)."""

    def __init__(self, era: Era = ERA) -> None:
        self.era = era
        self.group = MixerGroup()
        self.text = ""
        self.buffer_size = TEXT_BUFFER_SIZE[era]
        self.last_error: MixerRefusal | None = None

    def handle(self, values: Sequence[int]) -> ChunkResult:
        """Apply one page-52 write (its register words)."""
        payload = struct.pack(f"<{len(values)}H", *values)
        if len(payload) < HEADER_SIZE:
            return ChunkResult(None, False)
        magic, action = struct.unpack_from("<HB", payload)
        if magic != F2I_MIXER_MAGIC:
            return ChunkResult(None, False)  # [?] E14's reaction to a wrong magic: ignore
        text = payload[HEADER_SIZE:].decode("latin-1")
        if action == ACTION_RESET:
            self.group.reset()
            self.text = ""
            self.last_error = None
        elif action != ACTION_APPEND:
            return ChunkResult(None, False)
        # append (reset falls through): mixing is disabled while the text is incomplete
        if len(self.text) + len(text) + 1 > self.buffer_size:
            return ChunkResult(False, False)
        self.text += text
        mixers, resid, refusal = load_from_buf(self.text, self.era)
        for mixer in mixers:
            self.group.add(mixer)
        self.last_error = refusal
        if resid == len(self.text):
            return ChunkResult(False, False)
        self.text = self.text[len(self.text) - resid:]
        return ChunkResult(resid == 0, True)
