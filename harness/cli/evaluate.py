"""``tri360 evaluate``: argument parsing for :func:`harness.commands.evaluate.evaluate`."""

from __future__ import annotations

import argparse
from pathlib import Path

from harness.cli.cluster import add_cluster_arguments, run_context
from harness.cli.methods import add_method_options, add_results_options, selected_methods
from harness.cli.suite_options import add_suite_arguments, refuse_with_suite, suite_choice
from harness.commands.evaluate import evaluate, summary_text
from harness.commands.parts.suite import evaluate_suite

HELP = "run methods on every frame under a data root and score them against ground truth"
DESCRIPTION = (
    "Run methods on every frame under a data root and score them against ground truth; write a results set "
    "(and its report). Frames without ground truth (real captures, 'tri360 import'): when no frame of the data "
    "root has ground truth, the methods run and nothing is scored: the rows have empty metrics, valid_px 0 and "
    "the ground-truth-free quality figures (photometric residual, distance residual, pair agreement, uncertainty, "
    "calibration score), the maps are written with their quality maps, and the report shows distance, "
    "confidence and quality maps and point clouds. A data root that mixes frames with and without ground truth "
    "is refused (one line naming one of each: evaluate them into separate results sets), and so are "
    "--flow oracle and a --suite split without ground truth (docs/real-captures.md).")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = DESCRIPTION
    parser.add_argument("data_root", type=Path, metavar="DATA_ROOT",
                        help="folder holding <scene>/<viewpoint>/ frames (or one frame directory); all with ground "
                             "truth (scored) or all without (real captures: nothing scored)")
    add_method_options(parser, multiple=True)
    add_results_options(parser, "evaluate")
    add_suite_arguments(parser, "evaluate")
    add_cluster_arguments(parser)


def run(args) -> int:
    methods = selected_methods(args, multiple=True)
    suite = suite_choice(args)
    if suite is not None:
        refuse_with_suite(args, {"scene": None})
        table = evaluate_suite(args.data_root, suite[0], suite[1], args.out, methods, report=args.report,
                               ctx=run_context(args))
    else:
        table = evaluate(args.data_root, args.out, methods, args.scene, report=args.report,
                         ctx=run_context(args))
    print(f"\n{len(table)} results in {args.out / 'results.csv'}; per method, mean over frames:")
    print(summary_text(table))
    return 0
