"""The bounds of the self-calibration issue on a results set: does the default do no harm on cameras that agree,
and hold on every camera family?

Run as::

    tri360 evaluate DATA_ROOT --method fused-mirror fused-mirror-raw --out RESULTS
    python -m tools.research.check_calibration RESULTS [RESULTS ...] [--method fused-mirror]
        [--reference fused-mirror-raw]

``DATA_ROOT`` holds ideal frames and their twins of any conditions (e.g. ``python -m tools.research.render_subset``
with ``--suite suites/tri360-v3.toml``); several results sets are read as one (e.g. the ideal frames with both
methods in one, the twins of other conditions with the method alone in another).  Prints, as Markdown:

- per method the MAE (m) per condition (camera family) x room family, pooled over scored pixels, and the pooled MAE
  as a multiple of the pooled floor (``floor_m``: the MAE an ideal matcher with 0.25 px angular error per pair makes
  over the same pixels; "-" for results without it);
- **ideal**: the method's MAE over the reference's (the default without self-calibration), pooled per room family
  (bound :data:`IDEAL_FAMILY`) and per frame (bound :data:`IDEAL_FRAME`), with the worst frames;
- **each other condition**: its pooled MAE over the same method's on the ideal frames of the same groups (bound
  :data:`CONDITION_POOLED`) and the worst room family's ratio (bound :data:`CONDITION_FAMILY`).

Exit status 0 when every bound holds, 1 when one fails, 2 on bad input (one line).
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("check_calibration")

import sys
from pathlib import Path

import numpy as np
import pandas as pd

from harness.data.errors import UserError
from harness.data.results import read_results
from harness.data.suite import IDEAL
from tools.common import ArgumentParser, cell, goal_line, user_error

__all__ = ["IDEAL_FAMILY", "IDEAL_FRAME", "CONDITION_POOLED", "CONDITION_FAMILY", "pooled", "times_floor", "check",
           "main"]

PROG = "python -m tools.research.check_calibration"
IDEAL_FAMILY, IDEAL_FRAME = 1.03, 1.10
CONDITION_POOLED, CONDITION_FAMILY = 1.15, 1.3


def _group(scene: str) -> str:
    """The rendered frame's scene of a twin (``classroom-s1001.captured`` -> ``classroom-s1001``)."""
    return scene.split(".", 1)[0]


def pooled(rows: pd.DataFrame, column: str = "mae_m") -> float:
    """``column`` (an MAE in metres: ``mae_m``, ``floor_m``) over the rows' scored pixels together (each frame
    weighted by ``valid_px``), metres; NaN without scored pixels or without the column."""
    n = rows["valid_px"].to_numpy(np.float64)
    if column not in rows or n.sum() <= 0:
        return float("nan")
    return float((rows[column].to_numpy(np.float64) * n).sum() / n.sum())


def times_floor(rows: pd.DataFrame) -> str:
    """The rows' pooled MAE over their pooled floor, as a table cell ("-" without the floor)."""
    ratio = pooled(rows) / pooled(rows, "floor_m")
    return f"{ratio:.2f}" if np.isfinite(ratio) else "-"


def check(results: pd.DataFrame, method: str, reference: str) -> tuple[str, bool]:
    """The Markdown report of the module doc and whether every bound holds."""
    r = results.copy()
    r["condition"] = r["condition"].replace("", IDEAL)
    r["group"] = r["scene"].map(_group)
    r["family"] = r["family"].replace("", "?")
    for m in (method, reference):
        if m not in set(r["method"]):
            known = ", ".join(sorted(set(r["method"])))
            raise UserError(f"the results hold no rows of method {m!r} (methods: {known})")
    conditions = [IDEAL, *sorted(c for c in set(r["condition"]) if c != IDEAL)]
    families = sorted(set(r["family"]))
    lines = ["## MAE (m) per condition x room family", "",
             "| method | condition | all | x floor | " + " | ".join(families) + " |",
             "|---|---|---:|---:|" + "---:|" * len(families)]
    for m in sorted(set(r["method"])):
        for c in conditions:
            part = r[(r["method"] == m) & (r["condition"] == c)]
            if part.empty:
                continue
            cells = [cell(pooled(part[part["family"] == f])) if (part["family"] == f).any() else "-" for f in families]
            lines.append(f"| {m} | {c} | {cell(pooled(part))} | {times_floor(part)} | " + " | ".join(cells) + " |")
    goals = []
    ideal = r[r["condition"] == IDEAL]
    mine = ideal[ideal["method"] == method].set_index(["group", "viewpoint"])
    ref = ideal[ideal["method"] == reference].set_index(["group", "viewpoint"])
    both = mine.index.intersection(ref.index)
    if len(both):
        per_family = {f: pooled(mine.loc[both][mine.loc[both, "family"] == f])
                      / pooled(ref.loc[both][ref.loc[both, "family"] == f]) for f in families
                      if (mine.loc[both, "family"] == f).any()}
        per_frame = (mine.loc[both, "mae_m"] / ref.loc[both, "mae_m"]).sort_values(ascending=False)
        worst_f = max(per_family, key=per_family.get)
        goals.append((per_family[worst_f] <= IDEAL_FAMILY,
                      f"ideal: {method} / {reference} pooled per room family at most {IDEAL_FAMILY}: worst "
                      f"{worst_f} {per_family[worst_f]:.3f} (all: " + ", ".join(
                          f"{f} {v:.3f}" for f, v in per_family.items()) + ")"))
        goals.append((float(per_frame.iloc[0]) <= IDEAL_FRAME,
                      f"ideal: {method} / {reference} per frame at most {IDEAL_FRAME}: worst " + ", ".join(
                          f"{g}/{v} {x:.3f}" for (g, v), x in per_frame.iloc[:3].items())))
    for c in conditions[1:]:
        twins = r[(r["condition"] == c) & (r["method"] == method)]
        base = ideal[(ideal["method"] == method)
                     & ideal.set_index(["group", "viewpoint"]).index.isin(
                         twins.set_index(["group", "viewpoint"]).index)]
        if twins.empty or base.empty:
            continue
        ratio = pooled(twins) / pooled(base)
        fam = {f: pooled(twins[twins["family"] == f]) / pooled(base[base["family"] == f]) for f in families
               if (twins["family"] == f).any() and (base["family"] == f).any()}
        worst = max(fam, key=fam.get)
        goals.append((ratio <= CONDITION_POOLED, f"{c}: {method} pooled MAE over its ideal at most "
                                                 f"{CONDITION_POOLED}: {ratio:.3f}"))
        goals.append((fam[worst] <= CONDITION_FAMILY, f"{c}: worst room family at most {CONDITION_FAMILY}: "
                                                      f"{worst} {fam[worst]:.3f}"))
    lines += ["", "## Bounds", "", *(goal_line(ok, text) for ok, text in goals)]
    return "\n".join(lines) + "\n", all(ok for ok, _ in goals)


def main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(prog=PROG, description="the self-calibration issue's bounds on a results set")
    parser.add_argument("results", type=Path, nargs="+", metavar="RESULTS")
    parser.add_argument("--method", default="fused-mirror", help="the method checked (default: fused-mirror)")
    parser.add_argument("--reference", default="fused-mirror-raw",
                        help="the same method without self-calibration (default: fused-mirror-raw)")
    args = parser.parse_args(argv)
    try:
        table = pd.concat([read_results(r) for r in args.results], ignore_index=True)
        if table.duplicated(["scene", "viewpoint", "method"]).any():
            raise UserError("the results sets share a (scene, viewpoint, method) row: give each frame and method once")
        text, ok = check(table, args.method, args.reference)
    except UserError as exc:
        return user_error(PROG, exc)
    print(text)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(startup.run_main(main, "check_calibration"))
