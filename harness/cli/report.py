"""``tri360 report``: argument parsing for :func:`harness.commands.report.build_report`."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from harness.commands.report import DEFAULT_CLOUD_POINTS, PLY_CHOICES, build_report
from harness.data.errors import UserError
from harness.data.outputs import check_output, mark_output

HELP = "write tables, plots, point clouds and report.html from a results dir"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("results", type=Path, metavar="RESULTS",
                        help="results set written by `tri360 evaluate` or `tri360 score`; the report is written into "
                             "it, so it must hold only what tri360 wrote there (a directory holding anything else, a "
                             "data root or a predictions root is refused)")
    parser.add_argument("--ply", choices=PLY_CHOICES, default="all",
                        help="which point clouds to write as PLY: every configuration, only the paper set-up "
                             "(deepflow-rect), or none")
    parser.add_argument("--cloud-points", type=int, default=DEFAULT_CLOUD_POINTS, metavar="N",
                        help="points per cloud in the Fig. 3 style scatter views (a seeded subsample)")


def run(args) -> int:
    if args.cloud_points < 1:
        raise UserError(f"--cloud-points must be at least 1, got {args.cloud_points}")
    t0 = time.perf_counter()
    check_output(args.results, "results")  # writes only into a results set tri360 wrote
    out = build_report(args.results, ply=args.ply, cloud_points=args.cloud_points)
    mark_output(args.results, "results")
    print(out.markdown)
    for p in out.problems:
        print(f"tri360 report: warning: {p}", file=sys.stderr)
    print(f"wrote {len(out.files)} files in {time.perf_counter() - t0:.1f} s; open {out.html_path}")
    return 0
