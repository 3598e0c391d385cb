"""A command line whose errors are reported in one line, like every other bad value.

argparse exits with its own usage text on a bad option; :class:`OneLineParser` raises
:class:`UsageError` instead, so that a subcommand prints one line naming the value and exits 2.
"""

from __future__ import annotations

import argparse
from typing import NoReturn

__all__ = ["OneLineParser", "UsageError"]


class UsageError(ValueError):
    """A bad command line, reported in one line like every other bad value."""


class OneLineParser(argparse.ArgumentParser):
    """An :class:`argparse.ArgumentParser` whose errors raise :class:`UsageError`."""

    def error(self, message: str) -> NoReturn:
        raise UsageError(message)
