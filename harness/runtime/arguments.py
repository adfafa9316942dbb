"""The argument parser of every tri360 command and tool: an argument error is one line and exit status 2.

argparse prints the whole usage block before its error; here the error is ``<prog>: error: <message> (see `<prog>
--help`)`` alone on stderr.  This module imports nothing heavy, so a tool can use it without loading the commands.
"""

from __future__ import annotations

import argparse

__all__ = ["EXIT_USAGE", "ArgumentParser"]

EXIT_USAGE = 2
"""Exit status of an argument error, and of every anticipated failure."""


class ArgumentParser(argparse.ArgumentParser):
    """argparse's parser whose argument errors are one line and exit status :data:`EXIT_USAGE`."""

    def error(self, message: str):
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see `{self.prog} --help`)\n")
