"""``tri360 render``: argument parsing for :func:`harness.commands.render.render_frames`."""

from __future__ import annotations

import argparse
import os

from harness.cli.cluster import add_cluster_arguments, run_context
from harness.cli.suite_options import add_suite_arguments, refuse_with_suite, suite_choice
from harness.commands.parts.suite import render_suite
from harness.commands.render import (
    DEFAULT_SCENE,
    DEFAULTS,
    MIN_WIDTH,
    parse_overrides,
    render_frames,
    settings_from_options,
)
from harness.commands.study import LIMIT_FRAMES
from harness.render.registry import available_renderers
from reconstruction.camera.rig import DEFAULT_BASELINE_M

HELP = "render frames of a registered scene into a data root"


def add_arguments(parser) -> None:
    parser.add_argument("--scene", default=DEFAULT_SCENE, metavar="NAME[:PRESET]",
                        help="scene family and optional preset (see `tri360 scenes`)")
    parser.add_argument("--renderer", choices=available_renderers(), default=argparse.SUPPRESS,
                        help="cycles: Blender path tracer; raycast: numpy ray-caster, boxes only, no Blender "
                             "(default: the scene's own, shown by `tri360 scenes`)")
    parser.add_argument("--viewpoints", type=int, default=1, metavar="N", help="number of rig placements")
    parser.add_argument("--width", type=int, default=DEFAULTS.width,
                        help=f"panorama width in pixels (height = width/2); even, >= {MIN_WIDTH} (what the flow "
                             "backends can process), at most what fits in this machine's memory")
    parser.add_argument("--samples", type=int, default=DEFAULTS.samples,
                        help="Cycles samples per pixel (render time grows about linearly; see docs/rendering.md)")
    parser.add_argument("--seed", type=int, default=DEFAULTS.seed,
                        help="seed for layout jitter, viewpoints and render noise")
    parser.add_argument("--threads", type=int, default=DEFAULTS.threads, help="CPU threads for Cycles (0 = all)")
    parser.add_argument("--baseline", type=float, default=DEFAULT_BASELINE_M, help="rig baseline, metres")
    parser.add_argument("--max-bounces", type=int, default=DEFAULTS.max_bounces,
                        help=f"Cycles total light bounces (diffuse capped at {DEFAULTS.diffuse_bounces}, "
                             f"glossy at {DEFAULTS.glossy_bounces})")
    parser.add_argument("--light-tree", action=argparse.BooleanOptionalAction, default=DEFAULTS.light_tree,
                        help="Cycles' light tree: less noise per sample, but each sample costs about 1.8x as much; "
                             "off by default, which gives the same accuracy in less time (docs/rendering.md)")
    parser.add_argument("--no-denoise", action="store_true",
                        help="disable Cycles' OpenImageDenoise (much noisier colour, far worse reconstruction)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", dest="overrides",
                        help="override a scene parameter (value parsed as JSON if possible); repeatable; "
                             "an unknown KEY is an error that lists the scene's parameters, a value of the wrong "
                             "type or out of range one that says what it expects (tri360 scenes --params)")
    parser.add_argument("--out", default="data",
                        help="data root directory (frames go to OUT/<scene>/<viewpoint>/): absent, empty or a data "
                             "root tri360 wrote, holding only frames")
    parser.add_argument("--force", action="store_true",
                        help="re-render frames that are already complete (otherwise they are kept when rendered "
                             "with the same settings, and the run is refused when not)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--verbose", action="store_true", help="show Blender's own log output (on stderr)")
    add_suite_arguments(parser, "render")
    parser.add_argument("--yes", action="store_true",
                        help=f"with --suite: start a render of more than {LIMIT_FRAMES} frames (as `tri360 study`)")
    add_cluster_arguments(parser)


#: options a suite fixes (argparse dest -> default); --suite refuses them
SUITE_FIXED = {"scene": DEFAULT_SCENE, "renderer": None, "viewpoints": 1, "width": DEFAULTS.width,
               "samples": DEFAULTS.samples, "seed": DEFAULTS.seed, "baseline": DEFAULT_BASELINE_M,
               "max_bounces": DEFAULTS.max_bounces, "light_tree": DEFAULTS.light_tree, "no_denoise": False,
               "overrides": []}


def run(args) -> int:
    suite = suite_choice(args)
    if suite is not None:
        refuse_with_suite(args, SUITE_FIXED)
        dirs = render_suite(suite[0], suite[1], args.out, threads=args.threads, force=args.force,
                            ctx=run_context(args), yes=args.yes)
        for d in dirs:
            print(os.fspath(d))
        return 0
    dirs = render_frames(settings_from_options(vars(args)), args.scene, viewpoints=args.viewpoints,
                         out_root=args.out, baseline=args.baseline, overrides=parse_overrides(args.overrides),
                         renderer=getattr(args, "renderer", None), force=args.force,
                         ctx=run_context(args))
    for d in dirs:
        print(os.fspath(d))
    return 0
