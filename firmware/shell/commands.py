"""The table of built-in shell commands, gathered from the command files."""

from __future__ import annotations

from firmware.shell import builtins, cmd_mixer, cmd_param, cmd_status
from firmware.shell.interpreter import Command

__all__ = ["builtin_commands"]


def builtin_commands() -> dict[str, Command]:
    """A fresh table per shell, so a board may add or replace commands on its own shell."""
    table: dict[str, Command] = {}
    for group in (builtins.COMMANDS, cmd_param.COMMANDS, cmd_status.COMMANDS,
                  cmd_mixer.COMMANDS):
        for name, (fn, summary) in group.items():
            table[name] = Command(fn, summary)
    return table
