"""``tri360 export``: argument parsing for :func:`harness.commands.export.export`."""

from __future__ import annotations

import argparse
from pathlib import Path

from harness.cli.suite_options import add_suite_arguments, suite_choice
from harness.commands.export import export
from harness.commands.parts.suite import check_suite_data, load
from harness.data.layouts import LAYOUTS

HELP = "write frames in the dataset layout a learned 360 stereo method reads (3D60, Helvipad, 360SD-Net, Deep360)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("data", type=Path, metavar="DATA", help="data root (or one frame directory) to export")
    parser.add_argument("--format", required=True, choices=sorted(LAYOUTS), dest="layout",
                        help="the layout (docs/learned.md): " + "; ".join(f"{k}: {v.peer}" for k, v in LAYOUTS.items()))
    parser.add_argument("--out", type=Path, required=True, metavar="DIR",
                        help="directory to write the layout and manifest.json into: absent, empty or an export "
                             "tri360 wrote, never DATA, inside it or a parent of it")
    add_suite_arguments(parser, "export")


def run(args) -> int:
    suite = suite_choice(args)
    dirs = None
    if suite is not None:
        dirs = [r.path for r in check_suite_data(load(suite[0]), suite[1], args.data)]
    entries = export(args.data, args.layout, args.out, dirs, suite[1] if suite else None)
    print(f"exported {len(entries)} frame(s) in the {args.layout} layout -> {args.out} "
          f"(manifest: {args.out / 'manifest.json'})")
    return 0
