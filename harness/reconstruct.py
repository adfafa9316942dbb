"""``tri360 reconstruct``: per-pixel distance of camera C for one frame, one EXR per variant."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from tqdm import tqdm

from harness.errors import UserError
from harness.frame import atomic_write_text, read_frame, write_distance_exr
from reconstruction.flow import available_flows
from reconstruction.pipeline import DEFAULT_FLOW, Reconstruction, available_variants, reconstruct


def add_flow_options(parser: argparse.ArgumentParser, multiple: bool) -> None:
    """The flow / rectification / variant options shared by ``reconstruct`` and ``evaluate``."""
    if multiple:
        parser.add_argument("--flow", nargs="+", choices=available_flows(), default=None, metavar="NAME",
                            help=f"flow backends ({', '.join(available_flows())}); default: {DEFAULT_FLOW} on "
                                 "rectified pairs plus the paper's set-up (deepflow, no rectification)")
    else:
        parser.add_argument("--flow", choices=available_flows(), default=DEFAULT_FLOW, metavar="NAME",
                            help=f"flow backend: {', '.join(available_flows())}")
    parser.add_argument("--no-rectify", dest="rectify", action="store_false",
                        help="compute flow on the plain equirect images (the paper) instead of rectified pairs")
    parser.add_argument("--variants", nargs="+", default=None, metavar="NAME",
                        help=f"outputs to produce (default: all of {', '.join(available_variants())})")


def check_variants(names: list[str] | None) -> list[str]:
    known = available_variants()
    names = known if names is None else names
    bad = [n for n in names if n not in known]
    if bad:
        raise UserError(f"unknown variant(s) {', '.join(bad)} (known: {', '.join(known)})")
    return names


def run_with_progress(frame, flow: str, rectify: bool, variants: list[str], desc: str) -> Reconstruction:
    """:func:`reconstruct` with a stage progress bar; ValueError (e.g. oracle without GT) -> UserError."""
    stages = 3 + len([v for v in variants if v != "average"])
    with tqdm(total=stages, desc=desc, unit="stage", leave=False) as bar:
        def on_stage(name):
            bar.set_postfix_str(name)
            bar.update(1)
        try:
            return reconstruct(frame, flow=flow, rectify=rectify, variants=variants, on_stage=on_stage)
        except ValueError as exc:
            raise UserError(str(exc)) from None


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("frame_dir", type=Path, metavar="FRAME_DIR", help="a tri360-frame/1 directory")
    parser.add_argument("--out", type=Path, required=True, help="output directory for <variant>.distance.exr")
    add_flow_options(parser, multiple=False)


def run(args) -> int:
    variants = check_variants(args.variants)
    frame = read_frame(args.frame_dir)
    result = run_with_progress(frame, args.flow, args.rectify, variants, f"{frame.scene}/{frame.viewpoint}")
    args.out.mkdir(parents=True, exist_ok=True)
    for name in variants:
        write_distance_exr(args.out / f"{name}.distance.exr", result.distance[name])
    info = {"frame": str(args.frame_dir), "flow": args.flow, "rectify": args.rectify,
            "seconds": result.seconds, "lm_iterations": result.iterations}
    if frame.has_ground_truth:
        from reports.metrics import summary

        info["metrics"] = {name: summary(result.distance[name], frame.distance["C"]) for name in variants}
    atomic_write_text(args.out / "reconstruction.json", json.dumps(info, indent=2) + "\n")
    mode = "rectified" if args.rectify else "plain"
    print(f"{frame.scene}/{frame.viewpoint}  flow={args.flow} ({mode})  -> {args.out}")
    for name in variants:
        line = f"  {name:<10s}"
        if "metrics" in info:
            m = info["metrics"][name]
            line += f" MAE {m['mae_m']:.4f} m   median {m['median_m']:.4f} m   delta1 {m['delta1']:.3f}"
        print(line)
    print(f"  total {sum(result.seconds.values()):.2f} s")
    return 0
