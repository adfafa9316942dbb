"""``tri360 reconstruct``: argument parsing for :func:`harness.commands.reconstruct.reconstruct_to`."""

from __future__ import annotations

import argparse
from pathlib import Path

from harness.cli.cluster import run_context
from harness.cli.methods import add_method_options, selected_methods
from harness.commands.reconstruct import reconstruct_to

HELP = "reconstruct camera C's per-pixel distance of one frame with one method (writes tri360-pred/1)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("frame_dir", type=Path, metavar="FRAME_DIR", help="a tri360-frame/1 directory")
    parser.add_argument("--out", type=Path, required=True, metavar="PRED_ROOT",
                        help="predictions root: writes PRED_ROOT/<scene>/<viewpoint>/distance.exr (+ confidence.exr) "
                             "and PRED_ROOT/method.json, ready for `tri360 score`; it must be absent, empty or a "
                             "predictions root tri360 wrote with this same method (one method per root), never the "
                             "frame, inside it or a parent of it")
    add_method_options(parser, multiple=False)
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args) -> int:
    (method,) = selected_methods(args, multiple=False)
    info = reconstruct_to(args.frame_dir, args.out, method, run_context(args))
    line = f"{info['scene']}/{info['viewpoint']}  {method.label}  -> {args.out}"
    if "metrics" in info:
        m = info["metrics"]
        line += f"   MAE {m['mae_m']:.4f} m   median {m['median_m']:.4f} m   delta1 {m['delta1']:.3f}"
    print(line)
    print(f"  {info['seconds'].get('total', sum(info['seconds'].values())):.2f} s")
    return 0
