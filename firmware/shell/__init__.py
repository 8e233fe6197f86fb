"""The nsh-like shell of the emulated FMU (console, scripts, MAVLink SERIAL_CONTROL)."""

from firmware.shell.interpreter import Command, Shell

__all__ = ["Command", "Shell"]
