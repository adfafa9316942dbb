"""``tri360 evaluate``: argument parsing for :func:`harness.jobs.evaluate.evaluate`."""

from __future__ import annotations

import argparse
from pathlib import Path

from harness.cli.reconstruct import add_flow_options
from harness.jobs.evaluate import configurations, evaluate, mae_table
from harness.jobs.reconstruct import check_variants
from reports.build import write_report

HELP = "reconstruct and score every frame under a data root"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("data_root", type=Path, metavar="DATA_ROOT", help="folder holding <scene>/<viewpoint>/ frames")
    parser.add_argument("--out", type=Path, default=Path("results"), help="results directory")
    add_flow_options(parser, multiple=True)
    parser.add_argument("--scene", nargs="+", default=None, metavar="NAME", help="evaluate only these scenes")
    parser.add_argument("--report", action=argparse.BooleanOptionalAction, default=True,
                        help="write the report after the results (--no-report: results only)")


def run(args) -> int:
    variants = check_variants(args.variants)
    configs = configurations(args.flow, args.rectify)
    table = evaluate(args.data_root, args.out, configs, variants, args.scene)
    if args.report:
        write_report(args.out)
    print(f"\nMAE (m), mean over frames — {len(table)} rows in {args.out / 'results.csv'}")
    print(mae_table(table))
    return 0
