"""Component metadata (https://mavlink.io/en/services/component_information.html), as PX4 1.15.

QGroundControl asks a vehicle for COMPONENT_METADATA (#397; older versions
COMPONENT_INFORMATION, #395) and then downloads the files it names over MAVLink FTP:

* ``/etc/extras/component_general.json(.xz)``: the general metadata file, ``{"version": 1,
  "metadataTypes": [...]}`` with one entry per further file (its COMP_METADATA_TYPE, MAVLink
  FTP URI and CRC), as PX4's ``generate_component_general.py`` writes it; here the one further
  file is the parameter metadata;
* ``/etc/extras/parameters.json(.xz)``: every parameter's metadata in PX4's ``parameters.json``
  form (Tools/px4params/jsonout.py: ``version`` 1, ``uid`` 1, ``scope`` "Firmware", then per
  parameter name, type ``Int32``/``Float``, default, group, short and long description, units,
  decimal places, min, max, reboot required and the enumerated values), generated from the
  modules' ``ParamDef`` declarations, so a ground station's parameter editor shows ranges and
  descriptions without a table of its own.

The CRCs are PX4's "MAVLink CRC32" (reflected CRC-32 from 0, no final inversion, the same as
the FTP server's CalcFileCRC32) over the uncompressed file, as PX4's build computes them; a
ground station only compares them to decide whether its cached copy is still good. The URIs
name the ``.xz`` files, as PX4's do; the uncompressed files are served as well (the protocol
allows either). Everything is built on first request (the parameter file once, the xz copies
only when listed or opened): the declarations do not change after boot.
"""

from __future__ import annotations

import json
import lzma
import struct
from typing import Any, Final

from firmware.modules.mavlink.dialect import mav
from firmware.modules.mavlink.ftp import crc32_px4

__all__ = ["EXTRAS_DIR", "GENERAL_URI", "PARAMETERS_URI", "ComponentMetadata",
           "parameters_json"]

EXTRAS_DIR: Final = "etc/extras"
GENERAL_FILE: Final = "component_general.json"
PARAMETERS_FILE: Final = "parameters.json"
GENERAL_URI: Final = f"mftp://{EXTRAS_DIR}/{GENERAL_FILE}.xz"
PARAMETERS_URI: Final = f"mftp://{EXTRAS_DIR}/{PARAMETERS_FILE}.xz"


def _f32_text(value: float) -> float:
    """The shortest decimal that is still the same float32 (what the declaration said: 0.1,
    not 0.10000000149011612), as a float for JSON."""
    packed = struct.pack("<f", value)
    for digits in range(1, 10):
        short = float(f"{value:.{digits}g}")
        if struct.pack("<f", short) == packed:
            return short
    return value


def _number(value: float, is_int: bool) -> int | float:
    if is_int and float(value).is_integer():
        return int(value)
    return _f32_text(float(value))


def parameters_json(params: Any) -> bytes:
    """PX4's parameters.json for every declared parameter, in index (name) order."""
    out: list[dict[str, Any]] = []
    for name in params.names:
        d = params.defs[name]
        is_int = d.type == "INT32"
        entry: dict[str, Any] = {"name": name, "type": "Int32" if is_int else "Float",
                                 "default": _number(d.default, is_int), "group": d.group,
                                 "shortDesc": d.short or name}
        if d.long:
            entry["longDesc"] = d.long
        if d.unit:
            entry["units"] = d.unit
        if d.decimals is not None:
            entry["decimalPlaces"] = int(d.decimals)
        if d.min is not None:
            entry["min"] = _number(d.min, is_int)
        if d.max is not None:
            entry["max"] = _number(d.max, is_int)
        if d.reboot_required:
            entry["rebootRequired"] = True
        if d.values:
            entry["values"] = [{"value": int(v), "description": text}
                               for v, text in sorted(d.values.items())]
        out.append(entry)
    doc = {"version": 1, "uid": 1, "scope": "Firmware", "parameters": out}
    return json.dumps(doc, separators=(",", ":"), allow_nan=False).encode()


def _xz(data: bytes) -> bytes:
    return lzma.compress(data, format=lzma.FORMAT_XZ, check=lzma.CHECK_CRC64)


class ComponentMetadata:
    """The metadata files of the autopilot component, built from the board's parameters."""

    def __init__(self, params: Any) -> None:
        self.params = params
        self._general: bytes | None = None
        self._parameters: bytes | None = None
        self._files: dict[str, bytes] | None = None

    def parameters(self) -> bytes:
        if self._parameters is None:
            self._parameters = parameters_json(self.params) if self.params is not None else b""
        return self._parameters

    def general(self) -> bytes:
        if self._general is None:
            types: list[dict[str, Any]] = []
            if self.params is not None:
                types.append({"type": int(mav.COMP_METADATA_TYPE_PARAMETER),
                              "uri": PARAMETERS_URI, "fileCrc": crc32_px4(self.parameters())})
            self._general = json.dumps({"version": 1, "metadataTypes": types},
                                       separators=(",", ":")).encode()
        return self._general

    def files(self) -> dict[str, bytes]:
        """``/etc/extras``'s files by name (the FTP server's virtual folder)."""
        if self._files is None:
            general, parameters = self.general(), self.parameters()
            self._files = {GENERAL_FILE: general, GENERAL_FILE + ".xz": _xz(general)}
            if self.params is not None:
                self._files[PARAMETERS_FILE] = parameters
                self._files[PARAMETERS_FILE + ".xz"] = _xz(parameters)
        return self._files

    def message(self, msg_id: int, time_boot_ms: int) -> Any:
        """COMPONENT_METADATA or COMPONENT_INFORMATION (PX4 answers both with the general
        file's URI and CRC; no peripherals file)."""
        crc = crc32_px4(self.general())
        uri = GENERAL_URI.encode()
        if msg_id == mav.MAVLINK_MSG_ID_COMPONENT_INFORMATION:
            return mav.MAVLink_component_information_message(time_boot_ms, crc, uri, 0, b"")
        return mav.MAVLink_component_metadata_message(time_boot_ms, crc, uri)
