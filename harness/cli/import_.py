"""``tri360 import``: argument parsing for :func:`harness.commands.import_.import_frame`."""

from __future__ import annotations

import argparse
from pathlib import Path

from harness.commands.import_ import import_frame

HELP = "make a frame without ground truth from three real equirectangular images and a rig file"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    for name, what in (("C", "reference camera"), ("U", "camera above C"), ("R", "camera right of C")):
        parser.add_argument(name, type=Path, metavar=f"{name}_IMAGE", help=f"{what}: equirect JPEG or PNG, W = 2H")
    parser.add_argument("--rig", type=Path, required=True, metavar="RIG.json",
                        help="tri360-rig/1 file: poses of U and R relative to C, and optionally each camera's "
                             "photometric record, carried into frame.json (docs/real-captures.md; "
                             "examples/rig_paper_L_0.4m.json)")
    parser.add_argument("--out", type=Path, required=True, metavar="DATA/SCENE/VIEWPOINT",
                        help="frame directory to write; DATA must be absent, empty or a data root tri360 wrote")
    parser.add_argument("--width", type=int, default=None, help="resize the images to this width (height = width/2)")


def run(args) -> int:
    target = import_frame({"C": args.C, "U": args.U, "R": args.R}, args.rig, args.out, args.width)
    print(f"imported {target} (no ground truth)")
    return 0
