"""Choose the photometric self-calibration of the default method on a suite split, under both conditions.

Run as::

    python -m tools.research.select_photometric DATA_ROOT --out DIR [--suite suites/tri360-v2.toml] [--split dev]
        [--candidates LABEL ...] [--partial] [--workers N | --scheduler ADDRESS]

``DATA_ROOT`` holds the split's frames under both conditions (``tri360 render --suite suites/tri360-v2.toml
--split dev``: the rendered frames and their ``captured`` twins), checked as for ``tri360 evaluate --suite``;
``--partial`` evaluates whatever frames it holds instead (no suite check: a subset, said so in the output).  Every
candidate of :func:`candidate_methods` runs on every frame beside the comparison methods ``sweep`` and ``fused``
and the uncalibrated default ``fused-mirror-raw`` (the default's matching without self-calibration).  ``DIR``
becomes a results set plus ``selection.md`` and ``selection.json``: the method x condition x family MAE table
and the choice.

The rule (:func:`choose`), the bounds of the real-cameras issue: a candidate is *eligible* when

- on the captured frames its pooled MAE is at most :data:`CAPTURED_POOLED` times its own on the ideal frames, and
  on every family at most :data:`CAPTURED_FAMILY` times;
- on the ideal frames its pooled MAE is at most :data:`IDEAL_POOLED` times ``fused-mirror-raw``'s, and on every
  family at most :data:`IDEAL_FAMILY` times the better of ``sweep`` and ``fused``;

the choice is the eligible candidate with the lowest pooled MAE on the captured frames (when none is eligible:
the one whose worst ratio to its bounds is lowest, and the table says so).  Choose on ``dev`` only; run the test
split once with the chosen candidate (``--candidates``).
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("select_photometric")

import sys
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from harness.commands.evaluate import evaluate
from harness.commands.parts.suite import evaluate_suite
from harness.data.errors import UserError
from harness.data.suite import IDEAL
from reconstruction.methods.base import Method
from reconstruction.methods.presets import fused, fused_mirror, fused_mirror_raw
from reconstruction.methods.sweep import SweepMethod
from reports.tables import leaderboard_table
from tools.common import cell, run_selection, selection_parser
from tools.research.candidates import PHOTOMETRIC

__all__ = ["CAPTURED_POOLED", "CAPTURED_FAMILY", "IDEAL_POOLED", "IDEAL_FAMILY", "COMPARISON_METHODS",
           "UNCALIBRATED_DEFAULT", "CANDIDATES", "candidate_methods", "condition_table", "choose", "main"]

CAPTURED = "captured"
CAPTURED_POOLED, CAPTURED_FAMILY = 1.2, 1.3
IDEAL_POOLED, IDEAL_FAMILY = 1.03, 1.05
COMPARISON_METHODS = ("sweep", "fused")
UNCALIBRATED_DEFAULT = "fused-mirror-raw"
DEFAULT_SUITE = Path("suites/tri360-v2.toml")

#: the candidates (:data:`tools.research.candidates.PHOTOMETRIC`: label -> the self-calibration of the default's
#: matching and the sweep cost's intensity weight)
CANDIDATES = PHOTOMETRIC


def candidate_methods(only: Sequence[str] | None = None) -> list[Method]:
    """The comparison methods (``sweep``, ``fused``, as registered), ``fused-mirror-raw`` (the default's matching
    as it was: no self-calibration, intensity weight 1) and one ``fused-mirror`` per :data:`CANDIDATES` entry
    (``only``: these candidates; UserError for an unknown one)."""
    unknown = [x for x in (only or ()) if x not in CANDIDATES]
    if unknown:
        raise UserError(f"unknown candidate(s) {', '.join(unknown)} (candidates: {', '.join(CANDIDATES)})")
    base = fused_mirror()  # the candidates set the intensity weight themselves
    out: list[Method] = [SweepMethod(), fused(), fused_mirror_raw()]
    out += [c.method(base) for label, c in CANDIDATES.items() if only is None or label in only]
    return out


def condition_table(results: pd.DataFrame) -> pd.DataFrame:
    """Per method (index) and condition: pooled MAE (``<condition>``) and per family (``<condition>:<family>``),
    metres, pooled over scored pixels as the leaderboard pools them, and ``seconds`` summed over the frames."""
    results = results.copy()
    results["condition"] = results["condition"].replace("", IDEAL)
    rows = {}
    for cond in dict.fromkeys(results["condition"]):
        part = results[results["condition"] == cond].copy()
        part["condition"] = ""  # one condition: the leaderboard's plain family columns
        board = leaderboard_table(part)
        board = board[board["source"] == "tri360"].set_index("method")
        for m, row in board.iterrows():
            r = rows.setdefault(m, {})
            r[cond] = row["mae_m"]
            for c in board.columns:
                if c.startswith("mae_family:"):
                    r[f"{cond}:{c.split(':', 1)[1]}"] = row[c]
    table = pd.DataFrame.from_dict(rows, orient="index")
    table["seconds"] = results.groupby("method")["seconds"].sum(min_count=1)
    return table


def _families(table: pd.DataFrame, cond: str) -> list[str]:
    return [c.split(":", 1)[1] for c in table.columns if c.startswith(cond + ":")]


def ratios(table: pd.DataFrame) -> pd.DataFrame:
    """Per method, each bound's ratio (value / allowed; <= 1 meets it): ``captured``, ``captured_family`` (worst),
    ``ideal`` (against ``fused-mirror-raw``), ``ideal_family`` (worst, against the better baseline)."""
    fams = _families(table, IDEAL)
    out = pd.DataFrame(index=table.index)
    out["captured"] = table[CAPTURED] / table[IDEAL] / CAPTURED_POOLED
    cap = [f for f in _families(table, CAPTURED) if f in fams]
    out["captured_family"] = pd.concat([table[f"{CAPTURED}:{f}"] / table[f"{IDEAL}:{f}"] for f in cap],
                                       axis=1).max(axis=1) / CAPTURED_FAMILY
    out["ideal"] = table[IDEAL] / table.loc[UNCALIBRATED_DEFAULT, IDEAL] / IDEAL_POOLED
    best = table.loc[list(COMPARISON_METHODS), [f"{IDEAL}:{f}" for f in fams]].min(axis=0)
    out["ideal_family"] = (table[[f"{IDEAL}:{f}" for f in fams]] / best).max(axis=1) / IDEAL_FAMILY
    return out


def choose(table: pd.DataFrame) -> tuple[str, bool, pd.DataFrame]:
    """The rule of the module doc on a :func:`condition_table`: ``(label, eligible, ratios)``."""
    missing = [b for b in (*COMPARISON_METHODS, UNCALIBRATED_DEFAULT) if b not in table.index]
    if missing or IDEAL not in table.columns or CAPTURED not in table.columns:
        raise UserError(f"selection needs {', '.join([*COMPARISON_METHODS, UNCALIBRATED_DEFAULT])} on frames of "
                        f"both conditions ({IDEAL}, {CAPTURED})")
    r = ratios(table)
    worst = r.max(axis=1)
    cands = table.index.isin(list(CANDIDATES))
    eligible = (worst <= 1.0) & cands
    pool = table[eligible] if eligible.any() else table.loc[[worst[cands].idxmin()]]
    label = str(pool[CAPTURED].idxmin())
    return label, bool(eligible[label]), r


def selection_markdown(table: pd.DataFrame, label: str, eligible: bool, r: pd.DataFrame, where: str) -> str:
    """The selection as Markdown: per condition the method x family MAE table, the bound ratios and the choice."""
    lines = [f"# Photometric self-calibration: selection on {where}", "",
             f"Rule: eligible = captured MAE at most {CAPTURED_POOLED} x its ideal MAE pooled and {CAPTURED_FAMILY} x "
             f"on every family; ideal MAE at most {IDEAL_POOLED} x {UNCALIBRATED_DEFAULT}'s pooled and "
             f"{IDEAL_FAMILY} x the better of {' and '.join(COMPARISON_METHODS)} on every family; choice = the "
             "eligible candidate with the lowest captured MAE.", ""]
    for cond in (IDEAL, CAPTURED):
        fams = _families(table, cond)
        lines += [f"## MAE (m), {cond}", "", "| method | all | " + " | ".join(fams) + " |",
                  "|---|" + "---:|" * (len(fams) + 1)]
        for m, row in table.sort_values(cond).iterrows():
            cells = [cell(row[cond]), *(cell(row[f"{cond}:{f}"]) for f in fams)]
            lines.append(f"| {'**' + m + '**' if m == label else m} | " + " | ".join(cells) + " |")
        lines.append("")
    lines += ["## Bounds (ratio to the bound; at most 1 meets it)", "",
              "| method | captured / ideal | worst family | ideal / reference | ideal worst family | seconds |",
              "|---|---:|---:|---:|---:|---:|"]
    for m, row in r.iterrows():
        lines.append(f"| {m} | " + " | ".join(cell(x) for x in row) + f" | {table.loc[m, 'seconds']:.1f} |")
    verdict = "meets every bound" if eligible else "no candidate meets every bound: the lowest worst ratio"
    lines += ["", f"Chosen: `{label}` ({verdict}; captured MAE {table.loc[label, CAPTURED]:.4f} m, ideal "
                  f"{table.loc[label, IDEAL]:.4f} m)."]
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    parser = selection_parser(
        "tools.research.select_photometric", __doc__.splitlines()[0], DEFAULT_SUITE,
        "suite file (with a captured condition)",
        f"run only these candidates beside the comparison methods and {UNCALIBRATED_DEFAULT}")
    parser.add_argument("--partial", action="store_true",
                        help="evaluate the frames DATA_ROOT holds (a subset of the split), without the suite check")
    args = parser.parse_args(argv)

    def select(ctx) -> tuple[str, dict]:
        methods = candidate_methods(args.candidates)
        run = dict(report=False, ctx=ctx)
        if args.partial:
            results = evaluate(args.data_root, args.out, methods, **run)
            where_text = f"the frames of {args.data_root} (a subset of {args.suite.name} {args.split}, no suite check)"
        else:
            results = evaluate_suite(args.data_root, args.suite, args.split, args.out, methods, **run)
            where_text = f"{args.suite.name} ({results['suite_id'].iloc[0]}), split {args.split}"
        table = condition_table(results)
        label, eligible, r = choose(table)
        text = selection_markdown(table, label, eligible, r, where_text)
        payload = {"where": where_text, "chosen": label, "eligible": eligible,
                   "candidates": {k: c.record() for k, c in CANDIDATES.items()},
                   "ratios": {m: {k: float(v) for k, v in row.items()} for m, row in r.iterrows()},
                   "table": {m: {k: float(v) for k, v in row.items()} for m, row in table.iterrows()}}
        return text, payload

    return run_selection("select_photometric", args, select)


if __name__ == "__main__":
    sys.exit(startup.run_main(main, "select_photometric"))
