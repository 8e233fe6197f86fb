"""PX4IO link: CRC-8, packet layout, the worked byte examples of io-and-rc.md §1.5, the IO
request handler's reply rules, and a fuzz of the handler with random/corrupted packets."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from ioproc.pages import IoPages
from ioproc.protocol import (
    CRC8_TABLE,
    ERA,
    LAYOUT,
    PKT_MAX_REGS,
    BadCodeError,
    CrcError,
    Era,
    LengthError,
    PageNo,
    ReplyCode,
    StatusFlags,
    crc8,
    decode_reply,
    encode_read,
    encode_write,
    float_to_reg,
    handle_request,
    reg_to_float,
)
from tests.fuzzing import fuzz


def hx(text: str) -> bytes:
    return bytes.fromhex(text)


def test_era_is_single_choice() -> None:
    assert ERA is Era.E14


def test_crc8_check_value_and_table_rows() -> None:
    assert crc8(b"123456789") == 0xF4
    assert CRC8_TABLE[:16] == tuple(hx("00070E091C1B1215383F363124232A2D"))
    assert CRC8_TABLE[0x40:0x50] == tuple(hx("C7C0C9CEDBDCD5D2FFF8F1F6E3E4EDEA"))
    assert CRC8_TABLE[0xF0:] == tuple(hx("DED9D0D7C2C5CCCBE6E1E8EFFAFDF4F3"))


@pytest.mark.parametrize("built, wire", [
    (lambda: encode_read(0, 0, 1), "01 29 00 00 00 00"),
    (lambda: encode_read(0, 0, 1, padding=0x55AA), "01 1F 00 00 AA 55"),
    (lambda: LAYOUT.pack(ReplyCode.SUCCESS, 0, 0, [4]), "01 7D 00 00 04 00"),
    (lambda: LAYOUT.pack(ReplyCode.SUCCESS, 0, 0, [5]), "01 68 00 00 05 00"),
    (lambda: encode_write(50, 1, [3]), "41 8E 32 01 03 00"),
    (lambda: LAYOUT.pack(ReplyCode.SUCCESS, 50, 1, []), "00 D4 32 01"),
    (lambda: LAYOUT.pack(ReplyCode.ERROR, 50, 1, []), "80 E5 32 01"),
    (lambda: LAYOUT.pack(ReplyCode.CORRUPT, 0xFF, 0xFF, []), "40 BF FF FF"),
    (lambda: encode_read(1, 2, 6), "06 C6 01 02" + " 00" * 12),
    (lambda: encode_write(54, 0, [1500] * 8), "48 47 36 00" + " DC 05" * 8),
    (lambda: encode_write(50, 12, [22027]), "41 12 32 0C 0B 56"),
    (lambda: encode_write(50, 10, [14662]), "41 D7 32 0A 46 39"),
    (lambda: LAYOUT.pack(ReplyCode.SUCCESS, 1, 2, [0x3765, 0, 0, 0, 5000, 0]),
     "06 81 01 02 65 37 00 00 00 00 00 00 88 13 00 00"),
])
def test_worked_examples(built, wire: str) -> None:
    assert built() == hx(wire)


def test_layout_round_trip() -> None:
    pkt, ok = LAYOUT.unpack(hx("48 47 36 00" + " DC 05" * 8))
    assert ok and pkt.code == 0x40 and pkt.page == 54 and pkt.offset == 0
    assert pkt.regs == (1500,) * 8


def test_decode_reply_values_and_errors() -> None:
    reply = decode_reply(hx("01 7D 00 00 04 00"))
    assert reply.ok and reply.values == (4,) and (reply.page, reply.offset) == (0, 0)
    assert decode_reply(hx("80 E5 32 01")).code is ReplyCode.ERROR
    assert decode_reply(hx("40 BF FF FF")).code is ReplyCode.CORRUPT
    with pytest.raises(CrcError, match="CRC"):
        decode_reply(hx("01 7E 00 00 04 00"))
    with pytest.raises(LengthError):
        decode_reply(hx("01 7D 00 00 04"))  # IDLE before 4+2N bytes
    with pytest.raises(LengthError):
        decode_reply(b"\x00\xD4")
    bad = bytearray(LAYOUT.pack(0xC0, 1, 2, []))
    with pytest.raises(BadCodeError):
        decode_reply(bad)


def test_encoder_limits() -> None:
    with pytest.raises(ValueError):
        encode_read(0, 0, 33)
    with pytest.raises(ValueError):
        encode_write(0, 0, [0] * 33)
    with pytest.raises(ValueError):
        encode_write(0, 0, [0x10000])


def test_value_conventions() -> None:
    assert float_to_reg(0.5) == 5000
    assert float_to_reg(-0.12345) == (-1234) & 0xFFFF  # truncation toward zero
    assert reg_to_float(0xEC78) == pytest.approx(-0.5)


# --- the IO-side handler --------------------------------------------------------------------
@pytest.fixture
def regs() -> IoPages:
    return IoPages()


def transact(regs: IoPages, request: bytes, now_us: int = 0):
    reply = handle_request(request, regs, now_us)
    return None if reply is None else decode_reply(reply)


def test_handler_answers_worked_examples(regs: IoPages) -> None:
    assert handle_request(hx("01 29 00 00 00 00"), regs, 0) == hx("01 7D 00 00 04 00")
    assert handle_request(hx("41 8E 32 01 03 00"), regs, 0) == hx("00 D4 32 01")
    assert regs.arming == 3
    assert handle_request(hx("41 12 32 0C 0B 56"), regs, 0) == LAYOUT.pack(0, 50, 12, [])
    assert regs.status_flags & StatusFlags.SAFETY_OFF
    corrupt = bytearray(hx("41 8E 32 01 03 00"))
    corrupt[4] ^= 0x01
    assert handle_request(bytes(corrupt), regs, 0) == hx("40 BF FF FF")


def test_refused_write_example_and_partial_application(regs: IoPages) -> None:
    # SETUP regs 1..5: ARMING, PWM_RATES, DEFAULTRATE, ALTRATE applied; reg 5 refused
    request = encode_write(PageNo.SETUP, 1, [0x0001, 0, 50, 400, 7])
    assert handle_request(request, regs, 0) == hx("80 E5 32 01")
    assert regs.arming == 0x0001 and regs.page(PageNo.SETUP)[4] == 400


def test_bad_code_gets_corrupt_fffe(regs: IoPages) -> None:
    for code in (0x80, 0xC0):
        request = LAYOUT.pack(code, 0, 0, [0])
        reply = handle_request(request, regs, 0)
        assert reply == LAYOUT.pack(ReplyCode.CORRUPT, 0xFF, 0xFE, [])
        assert reply[0] == 0x40 and reply[2:] == hx("FF FE")


def test_short_request_gets_no_reply(regs: IoPages) -> None:
    assert handle_request(b"", regs, 0) is None
    assert handle_request(hx("01 29 00 00"), regs, 0) is None  # read without padding words
    assert handle_request(hx("01 29 00 00 00"), regs, 0) is None


def test_trailing_bytes_ignored(regs: IoPages) -> None:
    assert handle_request(hx("01 29 00 00 00 00 12 34"), regs, 0) == hx("01 7D 00 00 04 00")


def test_full_dma_buffer_with_oversized_count_is_corrupt(regs: IoPages) -> None:
    assert handle_request(bytes([0x21]) + bytes(67), regs, 0) == hx("40 BF FF FF")
    assert handle_request(bytes([0x21]) + bytes(60), regs, 0) is None


def test_read_truncated_at_page_end_and_max_regs(regs: IoPages) -> None:
    reply = transact(regs, encode_read(PageNo.CONFIG, 5, 10))
    assert reply.ok and reply.values == (8, 18, 2, 0)
    reply = transact(regs, encode_read(PageNo.RC_CONFIG, 0, 32))
    assert len(reply.values) == PKT_MAX_REGS
    assert reply.values[:6] == (1000, 1500, 2000, 30, 0, 1)


def test_unknown_page_and_offset_past_end(regs: IoPages) -> None:
    for page, offset in ((PageNo.SENSORS, 0), (PageNo.MIXERLOAD, 0), (PageNo.TEST, 0),
                         (200, 0), (PageNo.CONFIG, 9), (PageNo.STATUS, 9)):
        reply = transact(regs, encode_read(page, offset, 1))
        assert reply.code is ReplyCode.ERROR and reply.values == ()
        assert (reply.page, reply.offset) == (page, offset)


def test_write_reply_has_count_zero(regs: IoPages) -> None:
    reply = handle_request(encode_write(PageNo.CONTROLS, 0, [1000] * 8), regs, 5)
    assert reply[0] == 0x00 and len(reply) == 4


# --- fuzz ------------------------------------------------------------------------------------
def _check_reply(request: bytes, reply: bytes | None) -> None:
    if reply is None:
        count = request[0] & 0x3F if request else 0
        assert len(request) < 4 + 2 * count and len(request) < 68
        return
    decoded = decode_reply(reply)  # must be a well-formed packet with a good CRC
    if decoded.code is ReplyCode.CORRUPT:
        assert reply[2:4] in (b"\xff\xff", b"\xff\xfe") and len(reply) == 4
    else:
        assert (decoded.page, decoded.offset) == (request[2], request[3])
        if decoded.code is ReplyCode.ERROR or request[0] & 0x40:
            assert decoded.values == ()
        else:
            assert len(decoded.values) <= min(request[0] & 0x3F, PKT_MAX_REGS)


class StrictRegisters(IoPages):
    """Remembers any exception a page hook raised (the handler would only log it)."""

    def __init__(self) -> None:
        super().__init__()
        self.errors: list[BaseException] = []

    def read(self, page, offset):
        try:
            return super().read(page, offset)
        except Exception as exc:
            self.errors.append(exc)
            raise

    def write(self, page, offset, values, now_us):
        try:
            return super().write(page, offset, values, now_us)
        except Exception as exc:
            self.errors.append(exc)
            raise


@fuzz(examples=1500)
@given(st.binary(max_size=80))
def test_fuzz_random_bytes(data: bytes) -> None:
    regs = StrictRegisters()
    _check_reply(data, handle_request(data, regs, 1000))
    assert regs.errors == []


_PAGES = st.sampled_from([0, 1, 2, 3, 4, 5, 6, 7, 50, 51, 52, 53, 54, 55, 56, 106, 107, 108,
                          127, 255])


@fuzz(examples=500)
@given(code=st.sampled_from([0x00, 0x40]), page=_PAGES, offset=st.integers(0, 255),
       values=st.lists(st.integers(0, 0xFFFF), max_size=32),
       flip=st.none() | st.tuples(st.integers(0, 67), st.integers(1, 255)),
       cut=st.none() | st.integers(0, 67), flags=st.integers(0, 0xFFFF))
def test_fuzz_valid_and_corrupted_requests(code, page, offset, values, flip, cut,
                                           flags) -> None:
    regs = StrictRegisters()
    regs.status_flags = flags
    request = bytearray(LAYOUT.pack(code, page, offset, values))
    if flip is not None and flip[0] < len(request):
        request[flip[0]] ^= flip[1]
    if cut is not None:
        request = request[:cut]
    reply = handle_request(bytes(request), regs, 1000)
    _check_reply(bytes(request), reply)
    assert regs.errors == []
    if flip is None and cut is None:
        assert reply is not None and decode_reply(reply).code is not ReplyCode.CORRUPT
