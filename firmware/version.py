"""The firmware's identity as PX4 reports it: version words, the software hash, the OS, the UID.

One place for what AUTOPILOT_VERSION and the ULog's info keys (the ones Flight Review shows)
say, so the two never disagree:

* the flight software version word is PX4's ``0xMMmmpp TT`` (major, minor, patch, type; 255 an
  official release) from the emulator's version (``fmu-hil 0.1.0`` -> 0x000100FF);
* the software "git hash" (``ver_sw``, PX4's 40 hex characters): the build's hash when the
  board is given one (``System(git_hash=...)``, 40 hex characters), else the SHA-1 of the
  version string. It is not the tree's commit: the firmware must not read git at run time,
  and a log that changed with every commit could not be compared across commits or held to a
  golden digest; a hash of the version changes exactly when the version does;
* the OS is NuttX 7.10.0 (what PX4 ran on the FMUv2; AUTOPILOT_VERSION's os_sw_version);
* the MCU's unique ID (``sys_uuid``, 96 bits on the STM32): the emulator has no U_ID register,
  so it is the board name's first 12 bytes, as AUTOPILOT_VERSION's ``uid`` takes its first 8.
"""

from __future__ import annotations

import hashlib
import string
from typing import Final

__all__ = ["NUTTX_VERSION", "board_uid", "os_version_word", "software_hash", "version_word"]

NUTTX_VERSION: Final = (7, 10, 0)
#: PX4's FIRMWARE_VERSION_TYPE_OFFICIAL
TYPE_OFFICIAL: Final = 255


def version_word(version: str) -> int:
    """``"fmu-hil 1.2.3"`` -> PX4's (major << 24 | minor << 16 | patch << 8 | 255)."""
    nums = [int(x) for x in version.split()[-1].split(".")[:3] if x.isdigit()] + [0, 0, 0]
    return (nums[0] << 24) | (nums[1] << 16) | (nums[2] << 8) | TYPE_OFFICIAL


def os_version_word() -> int:
    major, minor, patch = NUTTX_VERSION
    return (major << 24) | (minor << 16) | (patch << 8) | TYPE_OFFICIAL


def software_hash(version: str, git_hash: str | None = None) -> str:
    """40 lower-case hex characters: ``git_hash`` if it is one, else SHA-1 of ``version``."""
    if git_hash is not None and len(git_hash) == 40 and \
            all(c in string.hexdigits for c in git_hash):
        return git_hash.lower()
    return hashlib.sha1(version.encode()).hexdigest()


def board_uid(board_name: str) -> bytes:
    """The emulated MCU's 12-byte unique ID."""
    return board_name.encode()[:12].ljust(12, b"\0")
