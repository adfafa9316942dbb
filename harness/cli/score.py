"""``tri360 score``: argument parsing for :func:`harness.commands.score.score`."""

from __future__ import annotations

import argparse
from pathlib import Path

from harness.cli.cluster import add_cluster_arguments, run_context
from harness.cli.methods import add_results_options
from harness.cli.suite_options import add_suite_arguments, refuse_with_suite, suite_choice
from harness.commands.evaluate import summary_text
from harness.commands.parts.suite import score_suite
from harness.commands.score import score, score_export
from harness.data.errors import UserError

HELP = "score predictions of any method (tri360-pred/1) against the ground truth of a data root"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("pred_roots", type=Path, nargs="+", metavar="PRED_ROOT",
                        help="predictions roots: PRED_ROOT/<scene>/<viewpoint>/distance.exr (+ confidence.exr)")
    parser.add_argument("--data", type=Path, required=True, metavar="DATA_ROOT",
                        help="the frames with ground truth (<scene>/<viewpoint>/, or one frame directory)")
    parser.add_argument("--method", nargs="+", action="extend", default=None, metavar="NAME",
                        help="one name per PRED_ROOT, in order (default: method.json's name, else the folder name); "
                             "a name becomes part of the maps' paths, so it may use only letters, digits and "
                             "_ . : + = - (no leading dot, no '..', at most 100 characters)")
    parser.add_argument("--export", type=Path, default=None, metavar="DIR",
                        help="PRED_ROOT holds a method's outputs in the layout of DIR, written by tri360 export "
                             "(depth or disparity as .npy/.exr/.png named after DIR's maps of C; docs/learned.md): "
                             "converted to C's distance, then scored")
    add_results_options(parser, "score")
    add_suite_arguments(parser, "score")
    add_cluster_arguments(parser)


def run(args) -> int:
    suite = suite_choice(args)
    if args.export is not None:
        if suite is not None or args.scene or len(args.pred_roots) != 1:
            raise UserError("--export takes one PRED_ROOT and no --suite or --scene (export the split instead)")
        table = score_export(args.pred_roots[0], args.export, args.data, args.out,
                             args.method[0] if args.method else None, report=args.report, ctx=run_context(args))
    elif suite is not None:
        refuse_with_suite(args, {"scene": None})
        table = score_suite(args.pred_roots, args.data, suite[0], suite[1], args.out, args.method,
                            report=args.report, ctx=run_context(args))
    else:
        table = score(args.pred_roots, args.data, args.out, args.method, args.scene, report=args.report,
                      ctx=run_context(args))
    print(f"\n{len(table)} results in {args.out / 'results.csv'}; per method, mean over frames:")
    print(summary_text(table))
    return 0
