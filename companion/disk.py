"""The companion's disk: a host file holding its parameters, as a Linux computer keeps them.

PX4 on Linux writes its parameters to a file (``parameters.bson`` beside its root file
system); here the file holds the same crash-safe two-slot store the FMU keeps in FRAM
(:class:`firmware.platform.params.ParamStorage`), so a save cut short keeps the previous copy
and a reboot of the companion loads what was saved.
"""

from __future__ import annotations

import os

__all__ = ["FilePartition", "PARAMS_FILE", "PARAMS_BYTES"]

#: the parameter file's name inside the companion's root folder
PARAMS_FILE = "parameters.bin"
#: two slots of 8 KiB: room for every parameter of the companion's modules many times over
PARAMS_BYTES = 16384


class FilePartition:
    """A fixed-size byte range in a host file (erased bytes 0xFF until written), with the
    ``read``/``write`` of a :class:`firmware.platform.params.Partition`."""

    def __init__(self, path: str, size: int = PARAMS_BYTES) -> None:
        if size <= 0:
            raise ValueError(f"partition size must be positive, got {size}")
        self.path = path
        self.size = size
        folder = os.path.dirname(os.path.abspath(path))
        os.makedirs(folder, exist_ok=True)
        if not os.path.exists(path) or os.path.getsize(path) != size:
            old = b""
            if os.path.exists(path):
                with open(path, "rb") as f:
                    old = f.read(size)
            with open(path, "wb") as f:
                f.write(old + b"\xff" * (size - len(old)))

    def read(self, offset: int, n: int) -> bytes | None:
        if offset < 0 or n < 0 or offset + n > self.size:
            return None
        with open(self.path, "rb") as f:
            f.seek(offset)
            return f.read(n)

    def write(self, offset: int, data: bytes) -> bool:
        if offset < 0 or offset + len(data) > self.size:
            return False
        with open(self.path, "r+b") as f:
            f.seek(offset)
            f.write(data)
        return True
