"""The ``--suite FILE --split NAME`` options of ``render``, ``evaluate`` and ``score`` (``docs/suites.md``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from harness.data.errors import UserError
from harness.data.suite import SPLITS

__all__ = ["add_suite_arguments", "suite_choice", "refuse_with_suite"]


def add_suite_arguments(parser: argparse.ArgumentParser, what: str) -> None:
    g = parser.add_argument_group("benchmark suite (docs/suites.md)")
    g.add_argument("--suite", type=Path, default=None, metavar="FILE",
                   help=f"{what} a suite's split (suites/*.toml); the suite fixes the frames and render settings")
    g.add_argument("--split", choices=SPLITS, default=None, help="the suite's split (required with --suite)")


def suite_choice(args) -> tuple[Path, str] | None:
    """``(suite file, split)`` when ``--suite`` is given, else None (UserError for --split without --suite or
    --suite without --split)."""
    if args.suite is None:
        if args.split is not None:
            raise UserError("--split needs --suite FILE")
        return None
    if args.split is None:
        raise UserError(f"--suite {args.suite} needs --split ({', '.join(SPLITS[:-1])} or {SPLITS[-1]})")
    return args.suite, args.split


def refuse_with_suite(args, defaults: dict) -> None:
    """UserError naming the first option that ``--suite`` fixes but that was given another value than its
    default (``defaults``: argparse dest -> default)."""
    for dest, default in defaults.items():
        if getattr(args, dest, default) != default:
            raise UserError(f"--{dest.replace('_', '-')} cannot be combined with --suite: the suite fixes it")
