"""``tri360 study``: argument parsing for :func:`harness.commands.study.run_study`."""

from __future__ import annotations

import argparse
from pathlib import Path

from harness.cli.cluster import add_cluster_arguments, run_context
from harness.commands.parts.robustness import is_robustness_study
from harness.commands.study import DEFAULT_METRIC, run_study

HELP = "render and evaluate every point of a grid of settings (a study TOML); write study.csv, plots, study.md"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("study", type=Path, metavar="STUDY.toml",
                        help="[render] (tri360 render options, dashes as underscores), [evaluate] (method, flow, "
                             "variants, rectify, report) and [grid] (a list of values for any of those keys); or a "
                             "robustness study: kind = \"robustness\", data, frames, method, seed and [levels] "
                             "(docs/robustness.md)")
    parser.add_argument("--out", type=Path, required=True, metavar="DIR",
                        help="study directory: study.csv, <key>.png, study.md, and the frames and results it reuses "
                             "when the study is rerun or extended; absent, empty or a study directory tri360 wrote "
                             "(holding nothing else), never around the study file")
    parser.add_argument("--metric", default=DEFAULT_METRIC, help="results column plotted against each grid key")
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
    parser.add_argument("--yes", action="store_true",
                        help="start a study past the size limits (more than 1000 grid points, more than 100 frames "
                             "to render or about 4 h of rendering), which is otherwise refused after saying its size")
    add_cluster_arguments(parser)


def run(args) -> int:
    table = run_study(args.study, args.out, run_context(args), metric=args.metric, yes=args.yes)
    name = "robustness" if is_robustness_study(args.study) else "study"
    print(f"{len(table)} rows in {args.out / (name + '.csv')}; plots and {name}.md in {args.out}")
    return 0
