"""PX4 mixer definition text -> mixers, with the parsing rules of the E14 IO.

Format (one tag per line, values are integers x10000):

    Z:                                          null mixer (one output, 0)
    M: <control count>                          simple mixer, followed by
    O: <-scale> <+scale> <offset> <lower> <upper>          its output scaler and
    S: <group> <index> <-scale> <+scale> <offset> <lower> <upper>   one line per control
    R: <geometry> <roll scale> <pitch scale> <yaw scale> <idle speed>   multirotor

The IO parses a *buffer* that grows chunk by chunk, so the rules matter (restated from PX4's
mixer library): a mixer is tried at any 'Z', 'M' or 'R'; any other byte is junk and skipped;
a mixer is refused while the buffer's last non-NUL byte is not a space/CR/LF (a number may be
cut); ``O:``/``S:`` tags are searched byte by byte; each line must end in CR or LF. The first
refusal stops the parse and leaves the rest in the buffer.

The FMU filters mixer files before sending (``filter_mixer_file``): only lines that start with
an upper-case letter and ':' survive, with runs of spaces compacted.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

from ioproc.mixer.base import Mixer, NullMixer, Scaler, SimpleInput, SimpleMixer
from ioproc.mixer.multirotor import GEOMETRIES, MultirotorMixer
from ioproc.protocol import ERA, Era

_C_SPACE = " \t\n\v\f\r"


class MixerParseError(ValueError):
    """A mixer definition the IO would refuse; ``line`` is 1-based in the text given."""

    def __init__(self, line: int, message: str) -> None:
        super().__init__(f"line {line}: {message}")
        self.line = line
        self.message = message


class MixerRefusal(Exception):
    """Why the IO stopped parsing at ``pos`` (where PX4's from_text returns nullptr)."""

    def __init__(self, pos: int, message: str) -> None:
        super().__init__(message)
        self.pos = pos
        self.message = message


#: digits converted at a time when wrapping a long number to 32 bits (below Python's limit on
#: int() of a long string)
_DIGIT_CHUNK: Final = 1000


def _c_long(negative: bool, digits: str) -> int:
    """The int NuttX's sscanf stores for %d (and, masked, %u) on the 32-bit STM32.

    NuttX's sscanf hands the digits to strtol/strtoul, which accumulate ``accum * 10 + digit``
    in an unsigned long without an overflow test, and negate for a '-'; %d stores the result
    as a (32-bit) int. So a number beyond the int range wraps modulo 2**32 rather than being
    refused: PX4's mixer parser never range-checks the scalers it reads (SimpleMixer's
    parse_output_scaler/parse_control_scaler divide by 10000 and store; scale_check() exists
    but neither from_text nor the IO's mixer_handle_text calls it). [?] whether the 2014
    NuttX strtoul saturated at ULONG_MAX instead: either way the value is a finite int32.
    """
    accum = 0
    for i in range(0, len(digits), _DIGIT_CHUNK):
        chunk = digits[i:i + _DIGIT_CHUNK]
        accum = (accum * 10 ** len(chunk) + int(chunk)) & 0xFFFFFFFF
    if negative:
        accum = -accum & 0xFFFFFFFF
    return accum - (1 << 32) if accum >= 1 << 31 else accum


def _scan_int(buf: str, pos: int) -> tuple[int, int] | None:
    """sscanf %d / %u: skip C whitespace, optional sign, >= 1 digit. Returns (value, end),
    the value as the 32-bit C int the IO stores (see :func:`_c_long`)."""
    n = len(buf)
    while pos < n and buf[pos] in _C_SPACE:
        pos += 1
    negative = pos < n and buf[pos] == "-"
    if pos < n and buf[pos] in "+-":
        pos += 1
    digits = pos
    while pos < n and "0" <= buf[pos] <= "9":
        pos += 1
    if pos == digits:
        return None
    return _c_long(negative, buf[digits:pos]), pos


def _scan_tag_ints(buf: str, pos: int, tag: str, count: int) -> list[int] | None:
    """sscanf(buf, "<tag>: %d %d ...") -> the values, or None when fewer than ``count`` match."""
    if not buf.startswith(tag + ":", pos):
        return None
    pos += 2
    values = []
    for _ in range(count):
        got = _scan_int(buf, pos)
        if got is None:
            return None
        value, pos = got
        values.append(value)
    return values


def _skipline(buf: str, pos: int) -> int | None:
    """Mixer::skipline: just past the first CR in the rest, else the first LF; None if neither."""
    p = buf.find("\r", pos)
    if p < 0:
        p = buf.find("\n", pos)
    return None if p < 0 else p + 1


def _findtag(buf: str, pos: int, tag: str) -> int | None:
    """Mixer::findtag: first position (byte by byte) where "<tag>:" starts."""
    p = buf.find(tag + ":", pos)
    return None if p < 0 else p


def _tail_ok(buf: str, pos: int) -> bool:
    """The buffer's last non-NUL byte must be space/CR/LF, else a token may be cut in two."""
    tail = buf[pos:].rstrip("\0")
    return not tail or tail[-1] in " \r\n"


def _parse_null(buf: str, pos: int) -> tuple[Mixer, int]:
    if not _tail_ok(buf, pos):
        raise MixerRefusal(pos, "incomplete: buffer does not end with a line end or space")
    if not buf.startswith("Z:", pos):
        raise MixerRefusal(pos, "expected 'Z:'")
    return NullMixer(), pos + 2  # only the tag is consumed; the rest of the line is junk


def _parse_simple(buf: str, pos: int) -> tuple[Mixer, int]:
    if not _tail_ok(buf, pos):
        raise MixerRefusal(pos, "incomplete: buffer does not end with a line end or space")
    head = _scan_tag_ints(buf, pos, "M", 1)
    if head is None:
        raise MixerRefusal(pos, "expected 'M: <control count>'")
    n_inputs = head[0] & 0xFFFFFFFF
    p = _skipline(buf, pos)
    if p is None:
        raise MixerRefusal(pos, "no line ending after 'M:'")
    tag = _findtag(buf, p, "O")
    if tag is None or len(buf) - tag < 12:
        raise MixerRefusal(p, "missing 'O:' output scaler line")
    vals = _scan_tag_ints(buf, tag, "O", 5)
    if vals is None:
        raise MixerRefusal(tag, "'O:' needs 5 integers: -scale +scale offset lower upper")
    p = _skipline(buf, tag)
    if p is None:
        raise MixerRefusal(tag, "no line ending after 'O:'")
    out_scaler = Scaler.from_ints(*vals)
    inputs = []
    for k in range(n_inputs):
        tag = _findtag(buf, p, "S")
        if tag is None or len(buf) - tag < 16:
            raise MixerRefusal(p, f"missing 'S:' line {k + 1} of {n_inputs}")
        vals = _scan_tag_ints(buf, tag, "S", 7)
        if vals is None:
            raise MixerRefusal(tag, "'S:' needs 7 integers: group index -scale +scale offset "
                                "lower upper")
        p = _skipline(buf, tag)
        if p is None:
            raise MixerRefusal(tag, "no line ending after 'S:'")
        inputs.append(SimpleInput(vals[0] & 0xFFFFFFFF, vals[1] & 0xFFFFFFFF,
                                  Scaler.from_ints(*vals[2:])))
    return SimpleMixer(out_scaler, tuple(inputs)), p


def _parse_multirotor(buf: str, pos: int, era: Era) -> tuple[Mixer, int]:
    if not _tail_ok(buf, pos):
        raise MixerRefusal(pos, "incomplete: buffer does not end with a line end or space")
    if not buf.startswith("R:", pos):
        raise MixerRefusal(pos, "expected 'R:'")
    p = pos + 2
    while p < len(buf) and buf[p] in _C_SPACE:
        p += 1
    end = p
    while end < len(buf) and buf[end] not in _C_SPACE and buf[end] != "\0":
        end += 1
    geometry = buf[p:end]
    if not geometry:
        raise MixerRefusal(pos, "'R:' needs <geometry> <roll> <pitch> <yaw> <idle>")
    vals = []
    p = end
    for _ in range(4):
        got = _scan_int(buf, p)
        if got is None:
            raise MixerRefusal(pos, "'R:' needs <geometry> <roll> <pitch> <yaw> <idle>")
        value, p = got
        vals.append(value)
    if _skipline(buf, pos) is None:
        raise MixerRefusal(pos, "no line ending after 'R:'")
    if len(geometry) > 7 or geometry not in GEOMETRIES[era]:  # geomname[8] in C
        raise MixerRefusal(pos, f"unrecognised geometry '{geometry}'")
    mixer = MultirotorMixer(geometry, *(v / 10000.0 for v in vals), era=era)
    return mixer, _skipline(buf, pos)  # type: ignore[return-value]


def load_from_buf(buf: str, era: Era = ERA) -> tuple[list[Mixer], int, MixerRefusal | None]:
    """MixerGroup::load_from_buf: parse what can be parsed from ``buf``.

    Returns (mixers, residual length, refusal or None). Junk bytes are consumed; on the first
    refusal the parse stops and ``buf[len(buf) - residual:]`` is what the IO keeps.
    """
    mixers: list[Mixer] = []
    pos = 0
    n = len(buf)
    while pos < n:
        c = buf[pos]
        try:
            if c == "Z":
                mixer, pos = _parse_null(buf, pos)
            elif c == "M":
                mixer, pos = _parse_simple(buf, pos)
            elif c == "R":
                mixer, pos = _parse_multirotor(buf, pos, era)
            else:
                pos += 1  # junk or whitespace
                continue
        except MixerRefusal as refusal:
            return mixers, n - pos, refusal
        mixers.append(mixer)
    return mixers, 0, None


def filter_mixer_file(text: str) -> str:
    """FMU side (load_mixer_file): keep only "<Upper>:" lines, compact runs of spaces."""
    return "".join(line for line, _ in _filtered_lines(text))


def _filtered_lines(text: str) -> list[tuple[str, int]]:
    kept = []
    for number, line in enumerate(text.splitlines(keepends=True), start=1):
        if len(line) < 2 or not ("A" <= line[0] <= "Z") or line[1] != ":":
            continue
        body = line.rstrip("\r\n")
        ending = line[len(body):]
        compact = " ".join(part for part in body.split(" ") if part)
        if body.endswith(" ") and ending:
            compact += " "
        kept.append((compact + ending, number))
    return kept


@dataclass(frozen=True)
class _LineMap:
    starts: tuple[int, ...]
    numbers: tuple[int, ...]

    def line_at(self, pos: int) -> int:
        line = self.numbers[0] if self.numbers else 1
        for start, number in zip(self.starts, self.numbers):
            if start > pos:
                break
            line = number
        return line


def parse_mixer_text(text: str, era: Era = ERA, *, filtered: bool = True) -> list[Mixer]:
    """Strictly parse a whole mixer definition (a ``.mix`` file) into mixers.

    With ``filtered`` the FMU's comment filter runs first, as in a real upload. Raises
    :class:`MixerParseError` naming the (original) line where the IO would stop parsing.
    """
    lines = _filtered_lines(text) if filtered else [
        (ln, i) for i, ln in enumerate(text.splitlines(keepends=True), start=1)]
    buf = "".join(ln for ln, _ in lines)
    if buf and not buf.endswith(("\n", "\r", " ")):
        buf += "\n"  # the FMU always sends a closing newline chunk
    starts, acc = [], 0
    for ln, _ in lines:
        starts.append(acc)
        acc += len(ln)
    line_map = _LineMap(tuple(starts), tuple(i for _, i in lines))
    mixers, resid, refusal = load_from_buf(buf, era)
    if refusal is not None:
        raise MixerParseError(line_map.line_at(refusal.pos), refusal.message)
    if resid:
        raise MixerParseError(line_map.line_at(len(buf) - resid), "unparsed text left over")
    return mixers
