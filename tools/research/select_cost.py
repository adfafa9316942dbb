"""Measure the default method with each per-pixel feature of the sweep cost, per camera condition.

Run as::

    NUMBA_NUM_THREADS=1 python -m tools.research.select_cost DATA_ROOT --out DIR [--frames LABEL ...]
        [--features FEATURE ...] [--quiet] [--workers N | --scheduler ADDRESS]

``LABEL`` is a frame directory (``<scene>/<viewpoint>``) or a directory of frames (``<scene>``) relative to
``DATA_ROOT``, e.g. ``office-s1041/vp000 office-s1041.captured/vp000 office-s1041.tone/vp000``; without
``--frames`` every frame under ``DATA_ROOT``.  The methods: ``fused-mirror`` (the default, the ``intensity``
feature), one ``fused-mirror-<feature>`` per other feature of :data:`reconstruction.sweep.cost.FEATURES`
(``--features``: these only) whose sweep uses that feature in both its costs (``cost`` and ``corrected_cost``,
everything else the default's) and the uncalibrated ``fused-mirror-raw`` (as registered).  ``DIR`` becomes a
results set (``tri360 evaluate``'s, without the report) plus ``selection.md`` and ``selection.json``: the method x
condition table of pooled MAE (metres; each frame weighted by its scored pixels, as the leaderboard pools) and the
MAE per frame.  A frame's condition is its ``frame.json``'s ``renderer.condition.name``, ``ideal`` without one.
Nothing is chosen: the table is what docs/cost.md reports.
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("select_cost")

import dataclasses
import os
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from harness.commands.evaluate import evaluate
from harness.data.errors import UserError
from harness.data.suite import IDEAL
from reconstruction.methods.base import Method
from reconstruction.methods.presets import fused_mirror
from reconstruction.methods.registry import get_methods
from reconstruction.sweep.cost import FEATURES
from tools.common import ArgumentParser, add_where_options, cell, run_selection

__all__ = ["PROG", "DEFAULT_LABEL", "RAW_LABEL", "feature_method", "candidate_methods", "link_frames",
           "frames_parser", "evaluate_frames", "with_condition", "pooled_mae", "condition_table", "frame_table",
           "selection_markdown", "main"]

PROG = "select_cost"
DEFAULT_LABEL = "fused-mirror"
RAW_LABEL = "fused-mirror-raw"


def feature_method(feature: str) -> Method:
    """``fused-mirror`` whose sweep compares ``feature`` (both its ``cost`` and its ``corrected_cost``; everything
    else the default's), labelled ``fused-mirror-<feature>`` (the default itself for ``intensity``)."""
    base = fused_mirror()
    if feature == base.sweep.cost.feature:
        return base
    sweep = base.sweep
    corrected = None if sweep.corrected_cost is None else dataclasses.replace(sweep.corrected_cost, feature=feature)
    sweep = dataclasses.replace(sweep, cost=dataclasses.replace(sweep.cost, feature=feature),
                                corrected_cost=corrected)
    return dataclasses.replace(base, sweep=sweep, label=f"{base.label}-{feature}")


def candidate_methods(features: Sequence[str] | None = None) -> list[Method]:
    """``fused-mirror``, one :func:`feature_method` per other feature (``features``: these only; UserError for an
    unknown one) and :data:`RAW_LABEL` (as registered: the default's matching without self-calibration)."""
    unknown = [f for f in (features or ()) if f not in FEATURES]
    if unknown:
        raise UserError(f"unknown feature(s) {', '.join(unknown)} (features: {', '.join(FEATURES)})")
    others = [f for f in FEATURES[1:] if features is None or f in features]
    return [fused_mirror(), *(feature_method(f) for f in others), *get_methods([RAW_LABEL])]


def link_frames(data_root: Path, labels: Sequence[str], into: Path) -> Path:
    """A data root in ``into`` holding a symbolic link per label (a frame directory or a directory of frames
    relative to ``data_root``) at the same relative path; UserError (one line) for a label that is absolute,
    leaves ``data_root`` or is not a directory there.  The results set records the frames' real paths."""
    root = Path(data_root).resolve()
    for label in labels:
        rel = Path(label)
        source = (root / rel).resolve()
        if rel.is_absolute() or ".." in rel.parts or not source.is_relative_to(root) or rel == Path("."):
            raise UserError(f"--frames {label}: not a directory below {data_root}")
        if not source.is_dir():
            raise UserError(f"--frames {label}: {data_root / rel} is not a directory")
        link = into / rel
        if os.path.lexists(link):
            continue
        link.parent.mkdir(parents=True, exist_ok=True)
        link.symlink_to(source, target_is_directory=True)
    return into


def frames_parser(prog: str, description: str) -> ArgumentParser:
    """The options of a script that evaluates methods on some frames of a data root: ``DATA_ROOT``, ``--out``,
    ``--frames``, ``--quiet`` and where to run (``--workers N`` | ``--scheduler ADDRESS``); the script adds its
    own."""
    parser = ArgumentParser(prog=f"python -m tools.research.{prog}", description=description)
    parser.add_argument("data_root", type=Path, metavar="DATA_ROOT")
    parser.add_argument("--out", type=Path, required=True, help="results set to write (with selection.md/json)")
    parser.add_argument("--frames", nargs="+", default=None, metavar="LABEL",
                        help="frame directories (<scene>/<viewpoint>) or directories of frames below DATA_ROOT "
                             "(default: every frame)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    add_where_options(parser)
    return parser


def evaluate_frames(data_root: Path, frames: Sequence[str] | None, out: Path, methods: Sequence[Method],
                    ctx) -> pd.DataFrame:
    """``tri360 evaluate`` without the report into ``out``: ``methods`` on the frames ``frames`` (labels as
    :func:`link_frames` takes them) below ``data_root``, or on every frame there (``frames`` None); ``ctx``: where
    to run (:class:`harness.runtime.context.RunContext`).  Returns the results' rows."""
    if not frames:
        return evaluate(data_root, out, methods, report=False, ctx=ctx)
    if not Path(data_root).is_dir():
        raise UserError(f"{data_root}: data root is not a directory")
    with tempfile.TemporaryDirectory(prefix="tri360-select-") as tmp:
        return evaluate(link_frames(data_root, frames, Path(tmp)), out, methods, inputs=[data_root], report=False,
                        ctx=ctx)


def with_condition(results: pd.DataFrame) -> pd.DataFrame:
    """A copy of results rows whose ``condition`` is ``ideal`` where it was empty (frames without a condition)."""
    results = results.copy()
    results["condition"] = results["condition"].fillna("").replace("", IDEAL)
    return results


def pooled_mae(rows: pd.DataFrame) -> float:
    """MAE pooled over the rows' scored pixels (each frame weighted by ``valid_px``), metres."""
    n = rows["valid_px"].astype(float)
    return float((rows["mae_m"] * n).sum() / n.sum()) if n.sum() > 0 else float("nan")


def condition_table(results: pd.DataFrame, methods: Sequence[str]) -> pd.DataFrame:
    """Method (index, in ``methods``' order) x condition (``ideal`` first, then as they appear): pooled MAE, metres
    (:func:`pooled_mae`), plus ``all`` (every frame) and ``seconds`` (summed over the frames)."""
    results = with_condition(results)
    conds = sorted(dict.fromkeys(results["condition"]), key=lambda c: c != IDEAL)
    table = pd.DataFrame(index=list(methods), columns=[*conds, "all", "seconds"], dtype=float)
    for m in methods:
        mine = results[results["method"] == m]
        for c in conds:
            table.loc[m, c] = pooled_mae(mine[mine["condition"] == c])
        table.loc[m, "all"] = pooled_mae(mine)
        table.loc[m, "seconds"] = float(mine["seconds"].sum())
    return table


def frame_table(results: pd.DataFrame, methods: Sequence[str]) -> pd.DataFrame:
    """Frame (index ``(condition, scene, viewpoint)``, sorted) x method (``methods``' order): MAE, metres."""
    results = with_condition(results)
    table = results.pivot_table(index=["condition", "scene", "viewpoint"], columns="method", values="mae_m")
    return table[[m for m in methods if m in table.columns]].sort_index(
        key=lambda idx: idx.map(lambda v: (v != IDEAL, v)) if idx.name == "condition" else idx)


def selection_markdown(conditions: pd.DataFrame, frames: pd.DataFrame, where: str) -> str:
    """The two tables as Markdown."""
    conds = [c for c in conditions.columns if c != "seconds"]
    lines = [f"# Sweep cost features on {where}", "",
             "Pooled MAE (m; each frame weighted by its scored pixels) per method and condition:", "",
             "| method | " + " | ".join(conds) + " | seconds |", "|---|" + "---:|" * (len(conds) + 1)]
    for m, row in conditions.iterrows():
        lines.append(f"| {m} | " + " | ".join(cell(row[c]) for c in conds) + f" | {row['seconds']:.0f} |")
    lines += ["", "MAE (m) per frame:", "", "| condition | frame | " + " | ".join(frames.columns) + " |",
              "|---|---|" + "---:|" * len(frames.columns)]
    for (cond, scene, vp), row in frames.iterrows():
        lines.append(f"| {cond} | {scene}/{vp} | " + " | ".join(cell(x) for x in row) + " |")
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    parser = frames_parser(PROG, __doc__.splitlines()[0])
    parser.add_argument("--features", nargs="+", default=None, metavar="FEATURE",
                        help=f"features beside the default intensity ({', '.join(FEATURES[1:])}; default: all)")
    args = parser.parse_args(argv)

    def select(ctx) -> tuple[str, dict]:
        methods = candidate_methods(args.features)
        labels = [m.label for m in methods]
        results = evaluate_frames(args.data_root, args.frames, args.out, methods, ctx)
        where = f"{'' if args.frames else 'the '}{len(results) // len(methods)} frames of {args.data_root}"
        conditions = condition_table(results, labels)
        frames = frame_table(results, labels)
        text = selection_markdown(conditions, frames, where)
        payload = {"where": where, "frames": args.frames, "methods": labels,
                   "pooled_mae_m": {m: {c: float(v) for c, v in row.items()} for m, row in conditions.iterrows()},
                   "frame_mae_m": [{"condition": c, "scene": s, "viewpoint": v, **{m: float(x) for m, x in row.items()}}
                                   for (c, s, v), row in frames.iterrows()]}
        return text, payload

    return run_selection(PROG, args, select)


if __name__ == "__main__":
    sys.exit(startup.run_main(main, PROG))
