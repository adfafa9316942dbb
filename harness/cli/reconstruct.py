"""``tri360 reconstruct``: argument parsing for :func:`harness.jobs.reconstruct.reconstruct_to`."""

from __future__ import annotations

import argparse
from pathlib import Path

from harness.jobs.reconstruct import check_variants, reconstruct_to
from reconstruction.flow.backends import available_flows
from reconstruction.methods.flow_pipeline import DEFAULT_FLOW, available_variants

HELP = "reconstruct per-pixel distance for one frame"


def add_flow_options(parser: argparse.ArgumentParser, multiple: bool) -> None:
    """The flow / rectification / variant options shared by ``reconstruct`` and ``evaluate``."""
    if multiple:
        parser.add_argument("--flow", nargs="+", choices=available_flows(), default=None, metavar="NAME",
                            help=f"flow backends ({', '.join(available_flows())}); default: {DEFAULT_FLOW} on "
                                 "rectified pairs plus the paper's set-up (deepflow, no rectification)")
    else:
        parser.add_argument("--flow", choices=available_flows(), default=DEFAULT_FLOW, metavar="NAME",
                            help=f"flow backend: {', '.join(available_flows())}")
    parser.add_argument("--rectify", action=argparse.BooleanOptionalAction, default=True,
                        help="compute flow on rectified pairs (baseline = polar axis); --no-rectify: on the plain "
                             "equirect images, as the paper does")
    parser.add_argument("--variants", nargs="+", default=None, metavar="NAME",
                        help=f"outputs to produce (default: all of {', '.join(available_variants())})")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("frame_dir", type=Path, metavar="FRAME_DIR", help="a tri360-frame/1 directory")
    parser.add_argument("--out", type=Path, required=True, help="output directory for <variant>.distance.exr")
    add_flow_options(parser, multiple=False)


def run(args) -> int:
    variants = check_variants(args.variants)
    info = reconstruct_to(args.frame_dir, args.out, args.flow, args.rectify, variants)
    mode = "rectified" if args.rectify else "plain"
    print(f"{info['scene']}/{info['viewpoint']}  flow={args.flow} ({mode})  -> {args.out}")
    for name in variants:
        line = f"  {name:<10s}"
        if "metrics" in info:
            m = info["metrics"][name]
            line += f" MAE {m['mae_m']:.4f} m   median {m['median_m']:.4f} m   delta1 {m['delta1']:.3f}"
        print(line)
    print(f"  total {sum(info['seconds'].values()):.2f} s")
    return 0
