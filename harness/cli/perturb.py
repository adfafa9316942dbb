"""``tri360 perturb``: argument parsing for :func:`harness.commands.perturb.perturb_root`."""

from __future__ import annotations

import argparse
from pathlib import Path

from harness.commands.parts.perturbations import KINDS, ORDER
from harness.commands.perturb import parse_applies, perturb_root

HELP = "derive frames with calibration error and imaging defects (same ground truth, provenance in frame.json)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("data", type=Path, metavar="DATA", help="data root (or one frame directory) to perturb")
    parser.add_argument("--out", type=Path, required=True, metavar="DATA2",
                        help="data root to write <scene>/<viewpoint>/ into: absent, empty or a data root tri360 "
                             "wrote, never DATA, inside it or a parent of it")
    kinds = "; ".join(f"{k} ({KINDS[k]})" for k in ORDER)
    parser.add_argument("--apply", action="append", default=[], metavar="KIND=LEVEL",
                        help=f"a perturbation, repeatable, applied in the fixed order listed: {kinds}")
    parser.add_argument("--seed", type=int, default=0, help="random seed (same seed: byte-identical frames)")


def run(args) -> int:
    applies = parse_applies(args.apply)
    written = perturb_root(args.data, args.out, applies, args.seed)
    what = ", ".join(f"{k}={v}" for k, v in applies)
    print(f"perturbed {len(written)} frame(s) ({what}, seed {args.seed}) -> {args.out}")
    return 0
