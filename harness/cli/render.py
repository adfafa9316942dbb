"""``tri360 render``: argument parsing for :func:`harness.jobs.render.render_frames`."""

from __future__ import annotations

import os

from harness.jobs.render import (
    DEFAULT_MAX_BOUNCES,
    DEFAULT_SAMPLES,
    DEFAULT_SCENE,
    DEFAULT_WIDTH,
    parse_overrides,
    render_frames,
)
from reconstruction.camera.rig import DEFAULT_BASELINE_M

HELP = "render frames of a registered scene into a data root"


def add_arguments(parser) -> None:
    parser.add_argument("--scene", default=DEFAULT_SCENE, metavar="NAME[:PRESET]",
                        help="scene family and optional preset (see `tri360 scenes`)")
    parser.add_argument("--viewpoints", type=int, default=1, metavar="N", help="number of rig placements")
    parser.add_argument("--width", type=int, default=DEFAULT_WIDTH, help="panorama width in pixels (height = width/2)")
    parser.add_argument("--samples", type=int, default=DEFAULT_SAMPLES,
                        help="Cycles samples per pixel (render time grows about linearly; see docs/rendering.md)")
    parser.add_argument("--seed", type=int, default=0, help="seed for layout jitter, viewpoints and render noise")
    parser.add_argument("--threads", type=int, default=0, help="CPU threads for Cycles (0 = all)")
    parser.add_argument("--baseline", type=float, default=DEFAULT_BASELINE_M, help="rig baseline, metres")
    parser.add_argument("--max-bounces", type=int, default=DEFAULT_MAX_BOUNCES,
                        help="Cycles total light bounces (diffuse capped at 3, glossy at 2)")
    parser.add_argument("--no-denoise", action="store_true",
                        help="disable OpenImageDenoise (much noisier colour, far worse reconstruction)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", dest="overrides",
                        help="override a scene parameter (value parsed as JSON if possible); repeatable")
    parser.add_argument("--out", default="data", help="data root directory")
    parser.add_argument("--force", action="store_true", help="re-render frames that are already complete")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--verbose", action="store_true", help="show Blender's own log output")


def run(args) -> int:
    dirs = render_frames(args.scene, viewpoints=args.viewpoints, out_root=args.out, width=args.width,
                         samples=args.samples, seed=args.seed, threads=args.threads, baseline=args.baseline,
                         force=args.force, denoise=not args.no_denoise, max_bounces=args.max_bounces,
                         overrides=parse_overrides(args.overrides), progress=not args.quiet,
                         verbose=args.verbose)
    for d in dirs:
        print(os.fspath(d))
    return 0
