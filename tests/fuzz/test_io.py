"""Fuzzing the IO's outside inputs: mixer text (both sides), the mixer upload in chunks, and
the FMU's px4io receive path."""

from __future__ import annotations

import math
import struct
from pathlib import Path

from hypothesis import given
from hypothesis import strategies as st

from ioproc.mixer import (MixerGroup, MixerParseError, MixerUpload, encode_mixer_upload,
                          filter_mixer_file, load_from_buf, parse_mixer_text)
from ioproc.pages import IoPages
from ioproc.protocol import (LAYOUT, PKT_COUNT_MASK, PageNo, ProtocolError, decode_reply,
                             encode_write, handle_request)
from tests.fuzzing import fuzz

MIXERS = [p.read_text() for p in
          sorted((Path(__file__).resolve().parents[2] / "firmware" / "romfs" / "mixers")
                 .glob("*.mix"))] + [
    "M: 2\nO: 10000 10000 0 -10000 10000\nS: 0 0 10000 10000 0 -10000 10000\n"
    "S: 0 2 -5000 -8000 1000 -10000 10000\nZ:\n",
    "R: 4x 10000 10000 10000 0\n", "R: 6+ 5000 5000 3000 1000\n"]
TOKENS = st.sampled_from(["M:", "O:", "S:", "R:", "Z:", " ", "\n", "\r", "\0", "-", "+", "4x",
                          "10000", "-10000", "0", "9" * 30, "9" * 400, "2147483648", "x"])


@st.composite
def mixer_texts(draw: st.DrawFn) -> str:
    """Random token soups, and real mixers with bytes flipped, cut or spliced."""
    if draw(st.booleans()):
        return "".join(draw(st.lists(TOKENS, max_size=60)))
    text = bytearray(draw(st.sampled_from(MIXERS)).encode("latin-1"))
    for _ in range(draw(st.integers(0, 4))):
        if text:
            i = draw(st.integers(0, len(text) - 1))
            if draw(st.booleans()):
                text[i] ^= 1 << draw(st.integers(0, 7))
            else:
                text[i:i] = draw(TOKENS).encode()
    if draw(st.booleans()):
        text = text[:draw(st.integers(0, len(text)))]
    return text.decode("latin-1")


def _controls(values: list[float]):
    return lambda group, index: values[(group * 8 + index) % len(values)]


@fuzz(examples=500)
@given(mixer_texts(), st.lists(st.floats(-1.0, 1.0), min_size=1, max_size=8))
def test_mixer_text_parses_or_is_refused_and_mixes_finite(text: str, controls) -> None:
    """Invariant: the strict parser (FMU filter + IO rules, filtered or not) gives mixers or
    MixerParseError with a line number; the IO's buffer parser never raises and consumes what
    it says, on the filtered text and on the raw one; every mixer's outputs for controls in
    [-1, 1] are finite."""
    groups = []
    for filtered in (True, False):
        try:
            groups.append(parse_mixer_text(text, filtered=filtered))
        except MixerParseError as err:
            assert err.line >= 1
    for buf in (filter_mixer_file(text), text):
        buf_mixers, resid, _ = load_from_buf(buf)
        assert 0 <= resid <= len(buf)
        groups.append(buf_mixers)
    for group_mixers in groups:
        group = MixerGroup()
        for m in group_mixers:
            group.add(m)
        outputs = group.mix(_controls(controls), 8)
        assert len(outputs) <= 8 and all(math.isfinite(o) for o in outputs)


@fuzz(examples=400)
@given(mixer_texts(), st.integers(8, 64))
def test_mixer_upload_in_chunks_keeps_registers_in_range(text: str, max_transfer: int) -> None:
    """Invariant: uploading any text through page 52 as the FMU does (chunks, closing
    newline) never raises on the IO, keeps its buffer under 256 bytes, and leaves
    FAILSAFE_PWM as uint16 registers (0..65535, E14's unclamped x600 + 1500)."""
    regs = IoPages()
    for words in encode_mixer_upload(text.encode("latin-1", "replace").decode("latin-1"),
                                     max_transfer):
        words = words[:32]  # one PX4IO packet carries at most 32 registers
        handle_request(encode_write(PageNo.MIXERLOAD, 0, words), regs, 0)
        assert len(regs.mixer.text) < 256
    assert all(0 <= v <= 0xFFFF for v in regs.values[PageNo.FAILSAFE_PWM])


@st.composite
def page52_writes(draw: st.DrawFn) -> list[list[int]]:
    """Page-52 writes as any sender could make them: a real mixer's upload with chunks
    dropped, repeated or reordered and magic, action or text bytes changed, or random chunks
    (good or bad magic, any action byte, odd lengths)."""
    if draw(st.booleans()):
        chunks = [struct.pack(f"<{len(w)}H", *w) for w in encode_mixer_upload(
            draw(st.sampled_from(MIXERS)), draw(st.integers(8, 64)))]
        for _ in range(draw(st.integers(1, 4))):
            i = draw(st.integers(0, len(chunks) - 1))
            how = draw(st.sampled_from(["drop", "repeat", "swap", "flip"]))
            if how == "drop" and len(chunks) > 1:
                del chunks[i]
            elif how == "repeat":
                chunks.insert(i, chunks[i])
            elif how == "swap":
                j = draw(st.integers(0, len(chunks) - 1))
                chunks[i], chunks[j] = chunks[j], chunks[i]
            else:  # a bit of the magic, the action or the text
                chunk = bytearray(chunks[i])
                bit = draw(st.integers(0, len(chunk) * 8 - 1))
                chunk[bit // 8] ^= 1 << (bit % 8)
                chunks[i] = bytes(chunk)
    else:
        chunks = [(b"\x74\x6d" if good else draw(st.binary(min_size=2, max_size=2)))
                  + bytes((action,)) + text
                  for good, action, text in draw(st.lists(st.tuples(
                      st.booleans(), st.integers(0, 255), st.binary(max_size=59)), max_size=12))]
    padded = [c + b"\0" * (len(c) % 2) for c in chunks]  # whole registers, as the FMU sends
    return [list(struct.unpack(f"<{len(c) // 2}H", c)) for c in padded]


@fuzz(examples=400)
@given(page52_writes())
def test_mixer_upload_of_any_chunks_keeps_the_buffer_bounded(writes: list[list[int]]) -> None:
    """Invariant: any sequence of page-52 writes (bad magic, unknown actions, appends without
    a reset, chunks out of order) is taken or ignored without raising; the IO's text buffer
    stays under its 256 bytes; the loaded mixers mix finite outputs."""
    upload = MixerUpload()
    for words in writes:
        upload.handle(words)
        assert len(upload.text) < 256
    outputs = upload.group.mix(_controls([0.3, -0.2, 0.1, 0.6]), 8)
    assert len(outputs) <= 8 and all(math.isfinite(o) for o in outputs)


@fuzz(examples=800)
@given(st.one_of(
    st.binary(min_size=4, max_size=70),
    st.builds(lambda code, page, off, vals, flip, cut: (flip, cut,
                                                        LAYOUT.pack(code, page, off, vals)),
              st.sampled_from([0x00, 0x40, 0x80, 0xC0]), st.integers(0, 255),
              st.integers(0, 255), st.lists(st.integers(0, 0xFFFF), max_size=32),
              st.tuples(st.integers(0, 67), st.integers(1, 255)), st.integers(0, 68))))
def test_fmu_receive_path_decodes_or_refuses_any_reply(data) -> None:
    """Invariant: a reply burst the px4io link's length check lets through is decoded by
    decode_reply into a Reply with 16-bit registers, or refused with a ProtocolError (which
    the link counts and retries); nothing else escapes."""
    if isinstance(data, tuple):
        (at, mask), cut, packet = data
        buf = bytearray(packet)
        if at < len(buf):
            buf[at] ^= mask
        data = bytes(buf[:max(cut, 4)])
    if len(data) < LAYOUT.header_size or len(data) < LAYOUT.size(data[0] & PKT_COUNT_MASK):
        return  # the link drops it as a short reply before decoding
    try:
        reply = decode_reply(data)
    except ProtocolError:
        return
    assert all(0 <= v <= 0xFFFF for v in reply.values)
    assert 0 <= reply.page <= 255 and 0 <= reply.offset <= 255
