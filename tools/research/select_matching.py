"""Choose the default matching method on a suite split: run every candidate, tabulate MAE per family, apply the rule.

Run as::

    python -m tools.research.select_matching DATA_ROOT --out DIR [--suite suites/tri360-v1.toml] [--split dev]
        [--candidates LABEL ...] [--workers N | --scheduler ADDRESS]

``DATA_ROOT`` must hold exactly the split's frames (``tri360 render --suite ... --split dev``; checked as for
``tri360 evaluate --suite``).  Every candidate of :func:`candidate_methods` runs on every frame, ``sweep`` and
``fused`` among them, the flow computed once per frame and the room-bound pass and cost volume once per frame for
all fused candidates (one group of shared work).  The rest of tri360's DIS pipeline (:data:`CONTEXT_METHODS`, the
``dis-rect`` variants, which share that flow) runs beside them so that the table holds every built-in method
on the same frames; they are context rows, not candidates.  ``--workers N`` runs one Dask task per frame on a
local cluster of N single-threaded workers (the sweep and the flow are single-threaded, so 2 workers on 2 cores
take about half the time).  ``DIR`` becomes a results set (``results.csv``, leaderboard,
``config.json`` with the suite id and split) plus ``selection.md`` and ``selection.json``: the method x family
table (MAE and solid-angle-weighted MAE, pooled over each family's scored pixels as in the leaderboard) and the
choice.

The rule (:func:`choose`): a candidate is *eligible* when on every family its MAE is at most ``1 + TOLERANCE``
times the better of ``sweep`` and ``fused`` there, and its time summed over the split's frames (the ``seconds``
column: each method's stages as they would take alone, the shared flow included) is at most ``1 +
TIME_TOLERANCE`` times ``fused``'s in the same run (the default must not cost more than the method it replaces);
the choice is the eligible candidate with the lowest pooled MAE over the split (when none is eligible: the one
whose worst family ratio is lowest, and the table says so).  Choose
on ``dev`` only; run ``--split test`` once, with the chosen method among the candidates, to report it:
``--candidates fused-gated`` runs that one beside the comparison methods and the context rows, so the test run does not
look at the candidates that were not chosen.
"""

from __future__ import annotations

import argparse

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("select_matching")

import sys
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from harness.commands.parts.suite import evaluate_suite
from harness.data.errors import UserError
from reconstruction.methods.base import Method
from reconstruction.methods.presets import fused, fused_adaptive, fused_gated, fused_mirror
from reconstruction.methods.registry import DEFAULT_VARIANTS, get_methods
from reconstruction.methods.sweep import SweepMethod
from reports.tables import leaderboard_table
from tools.common import cell, run_selection, selection_parser
from tools.research.candidates import MATCHING, WALL_PLANES

__all__ = ["TOLERANCE", "TIME_TOLERANCE", "COMPARISON_METHODS", "CANDIDATES", "CONTEXT_METHODS", "candidate_methods",
           "family_table", "choose", "main"]

TOLERANCE = 0.05
#: a candidate's summed seconds may exceed ``fused``'s by this fraction (0: no slower)
TIME_TOLERANCE = 0.0
#: the methods every candidate is compared with: on each family at most ``1 + TOLERANCE`` x the better of them
COMPARISON_METHODS = ("sweep", "fused")
DEFAULT_SUITE = Path("suites/tri360-v1.toml")

#: the fused candidates besides the registered ones (:data:`tools.research.candidates.MATCHING`: label -> plane
#: families, prior weight per pixel and where the prior comes from)
CANDIDATES = MATCHING


#: built-in methods run beside the candidates for the table, not chosen from: tri360's DIS flow pipeline
CONTEXT_METHODS = tuple(f"dis-rect:{v}" for v in DEFAULT_VARIANTS)


def candidate_methods(only: Sequence[str] | None = None) -> list[Method]:
    """``sweep``, ``fused``, the sweep with wall families (``sweep-walls``), ``fused-adaptive``, ``fused-gated``,
    the default ``fused-mirror`` (:func:`reconstruction.methods.presets.fused_mirror`) and one fused method per
    :data:`CANDIDATES` entry (:meth:`tools.research.candidates.MatchingCandidate.method`: ``fused``'s flow, or
    ``dis-rect:average`` for a candidate with ``average_prior``; ``fused``'s sweep with the candidate's plane
    families).

    Args:
        only: candidate labels to keep (None = all); the :data:`COMPARISON_METHODS` are always kept, first.
    Raises:
        UserError: a label in ``only`` that is not a candidate (the message lists them).
    """
    base = fused()
    average = get_methods(["dis-rect:average"])[0]
    out: list[Method] = [SweepMethod(), base, SweepMethod(planes=WALL_PLANES, label="sweep-walls"), fused_adaptive(),
                         fused_gated(), fused_mirror()]
    out += [c.method(base, average) for c in CANDIDATES.values()]
    if only is None:
        return out
    known = [m.label for m in out]
    unknown = [x for x in only if x not in known]
    if unknown:
        raise UserError(f"unknown candidate(s) {', '.join(unknown)} (candidates: {', '.join(known)})")
    return [m for m in out if m.label in COMPARISON_METHODS or m.label in only]


def family_table(results: pd.DataFrame) -> pd.DataFrame:
    """Per method: pooled ``mae_m`` and ``mae_sw_m`` over the split and ``mae_family:<f>`` / ``mae_sw_family:<f>``
    per family (metres), as the leaderboard pools them, and ``seconds``, the method's time summed over the frames;
    one row per method, index ``method``."""
    board = leaderboard_table(results)
    board = board[board["source"] == "tri360"].set_index("method")
    board["seconds"] = results.groupby("method")["seconds"].sum(min_count=1)
    cols = ["frames", "mae_m", "mae_sw_m", "seconds",
            *sorted(c for c in board.columns if c.startswith("mae_family:")),
            *sorted(c for c in board.columns if c.startswith("mae_sw_family:"))]
    return board[cols]


def choose(table: pd.DataFrame, tolerance: float = TOLERANCE,
           context: Sequence[str] = CONTEXT_METHODS,
           time_tolerance: float | None = TIME_TOLERANCE) -> tuple[str, bool, pd.Series]:
    """Apply the selection rule to a :func:`family_table`; rows named in ``context`` are never chosen.

    Args:
        time_tolerance: with a ``seconds`` column, a method is eligible only when its seconds are at most
            ``1 + time_tolerance`` times ``fused``'s; None = no time bound.
    Returns:
        ``(label, eligible, worst)``: the chosen method, whether it meets the bounds (every family, and the time),
        and per method the worst ratio of its family MAE to the better of the comparison methods' (dimensionless).
    Raises:
        UserError: a comparison method is missing from the table.
    """
    missing = [b for b in COMPARISON_METHODS if b not in table.index]
    if missing:
        raise UserError(f"selection needs the comparison methods {', '.join(missing)} in the results")
    fams = [c for c in table.columns if c.startswith("mae_family:")]
    best = table.loc[list(COMPARISON_METHODS), fams].min(axis=0)
    worst = (table[fams] / best).max(axis=1)
    eligible = worst <= 1.0 + tolerance
    if time_tolerance is not None and "seconds" in table.columns:
        eligible &= table["seconds"] <= table.loc["fused", "seconds"] * (1.0 + time_tolerance)
    cands = ~table.index.isin(list(context))
    pool = table[eligible & cands] if (eligible & cands).any() else table.loc[[worst[cands].idxmin()]]
    label = str(pool["mae_m"].idxmin())
    return label, bool(eligible[label]), worst


def selection_markdown(table: pd.DataFrame, label: str, eligible: bool, worst: pd.Series, suite: str,
                       split: str, tolerance: float = TOLERANCE, time_tolerance: float = TIME_TOLERANCE) -> str:
    """The selection as Markdown: the method x family MAE table (plain, then solid-angle weighted; each with the
    worst family ratio and the summed seconds over ``fused``'s) and the choice."""
    fams = [c.split(":", 1)[1] for c in table.columns if c.startswith("mae_family:")]
    time_ratio = table["seconds"] / table.loc["fused", "seconds"]

    lines = [f"# Matching selection on {suite}, split {split}", "",
             f"Rule: eligible = MAE on every family at most {1 + tolerance:.2f} x the better of "
             f"{' and '.join(COMPARISON_METHODS)}, and seconds summed over the frames at most "
             f"{1 + time_tolerance:.2f} x "
             "fused's; choice = the eligible method with the lowest pooled MAE.", ""]
    for title, prefix, pooled in (("MAE (m)", "mae_family:", "mae_m"),
                                  ("solid-angle-weighted MAE (m)", "mae_sw_family:", "mae_sw_m")):
        lines += [f"## {title}", "", "| method | all | " + " | ".join(fams) + " | worst ratio | time / fused |",
                  "|---|" + "---:|" * (len(fams) + 3)]
        for m, row in table.sort_values(pooled).iterrows():
            cells = [cell(row[pooled]), *(cell(row[prefix + f]) for f in fams), f"{worst[m]:.2f}",
                     f"{time_ratio[m]:.2f}"]
            lines.append(f"| {'**' + m + '**' if m == label else m} | " + " | ".join(cells) + " |")
        lines.append("")
    verdict = "meets the bounds" if eligible else "no method meets the bounds: the lowest worst family ratio"
    lines.append(f"Chosen: `{label}` ({verdict}; pooled MAE {table.loc[label, 'mae_m']:.4f} m).")
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    parser = selection_parser(
        "tools.research.select_matching", __doc__.splitlines()[0], DEFAULT_SUITE, "suite file",
        "run only these candidates beside the comparison methods (sweep, fused), e.g. the method chosen on dev for "
        "the one test run (default: every candidate)")
    parser.add_argument("--no-context-rows", action="store_true",
                        help=f"run the candidates only, not the context rows ({', '.join(CONTEXT_METHODS)})")
    parser.add_argument("--no-references", dest="no_context_rows", action="store_true",
                        help=argparse.SUPPRESS)  # the option's former spelling
    args = parser.parse_args(argv)

    def select(ctx) -> tuple[str, dict]:
        context = [] if args.no_context_rows else get_methods(list(CONTEXT_METHODS))
        methods = candidate_methods(args.candidates) + context
        results = evaluate_suite(args.data_root, args.suite, args.split, args.out, methods, report=False,
                                 ctx=ctx)
        table = family_table(results)
        label, eligible, worst = choose(table)
        suite_id = str(results["suite_id"].iloc[0])
        text = selection_markdown(table, label, eligible, worst, f"{args.suite.name} ({suite_id})", args.split)
        payload = {"suite": str(args.suite), "suite_id": suite_id, "split": args.split, "tolerance": TOLERANCE,
                   "time_tolerance": TIME_TOLERANCE, "chosen": label, "eligible": eligible,
                   "worst_ratio": {k: float(v) for k, v in worst.items()},
                   "table": {m: {k: float(v) for k, v in row.items()} for m, row in table.iterrows()}}
        return text, payload

    return run_selection("select_matching", args, select)


if __name__ == "__main__":
    sys.exit(startup.run_main(main, "select_matching"))
