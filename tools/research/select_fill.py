"""Choose the default's sweep resolution and refill of its least confident pixels, per region, family and condition.

Run as::

    python -m tools.research.select_fill DATA_ROOT --out DIR [--frames LABEL ...] [--candidates NAME ...]
        [--quiet] [--workers N | --scheduler ADDRESS]

``LABEL`` is a frame directory (``<scene>/<viewpoint>``) or a directory of frames (``<scene>``) relative to
``DATA_ROOT``; without ``--frames`` every frame under ``DATA_ROOT`` (choose on a suite's ``dev`` split).  The
methods: the reference :data:`REFERENCE` (``fused-mirror-160-0-8-inverse``: 160 sphere labels, no pixel refilled,
as the default was before this choice), one ``fused-mirror-<levels>-<confidence>-<sigma>-<space>`` per candidate of
:data:`CANDIDATES` (``--candidates``: these only; everything but the sweep costs' ``levels`` and the sweep's
``PostParams.min_confidence``, ``fill_sigma_color`` and ``fill_space`` the default's) and the default
``fused-mirror`` as registered (a candidate configured as the default is the default, not run twice).  ``DIR``
becomes a results set (``tri360 evaluate``'s, without the report) plus ``selection.md`` and ``selection.json``:
pooled MAE (metres; each frame weighted by its scored pixels, as the leaderboard pools) per method and region
(``reports.regions``), and per method, camera condition and room family; and the choice.

The rule (:func:`choose`): a candidate (the default among them) is *eligible* when its pooled MAE on every
(condition, room family) is at most :data:`FAMILY_BOUND` times the reference's, its MAE on every frame at most
:data:`FRAME_BOUND` times the reference's, and it has at most :data:`MAX_LEVELS` sphere labels (memory); the
choice is the eligible candidate (or the reference) with the lowest pooled MAE over all frames.
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("select_fill")

import dataclasses
import sys
from collections.abc import Callable, Sequence

import numpy as np
import pandas as pd

from harness.data.errors import UserError
from harness.data.suite import IDEAL
from reconstruction.methods.base import Method
from reconstruction.methods.presets import fused_mirror
from tools.common import cell, run_selection
from tools.research.select_cost import evaluate_frames, frames_parser, pooled_mae, with_condition

__all__ = ["PROG", "REFERENCE", "FAMILY_BOUND", "FRAME_BOUND", "MAX_LEVELS", "CANDIDATES", "config_name",
           "fill_method", "candidate_methods", "methods_to_compare", "region_table", "family_table", "frame_table",
           "choose", "selection_markdown", "select", "candidates_main", "main"]

PROG = "select_fill"
TITLE = "Sweep resolution and the refill of the least confident pixels"
#: a candidate's pooled MAE on every (condition, room family) at most this times the reference's (1.0 at first; the
#: captured classroom frames at 1.002 x, 0.001 m, made it 1.02: docs/edges.md)
FAMILY_BOUND = 1.02
#: a candidate's MAE on every frame at most this times the reference's (the pooled bound can hide one frame's loss: a
#: default that loses badly on any frame is not better)
FRAME_BOUND = 1.10
#: the most sphere labels an eligible candidate may have: the default's peak memory at 1000x500 within the 1 GB a
#: frame may take (``python -m tools.bench.sweep``: 0.93 GB with 200 labels, 1.01 GB with 240)
MAX_LEVELS = 200
#: a configuration: (sphere labels of both sweep costs, min_confidence, fill_sigma_color in 8-bit gray levels,
#: fill_space); fill_lambda the default's
Config = tuple[int, float, float, str]
#: the reference: the default as it was before this choice (160 labels, nothing refilled)
REFERENCE: Config = (160, 0.0, 8.0, "inverse")
#: the candidates
CANDIDATES: tuple[Config, ...] = (
    (160, 0.05, 8.0, "inverse"), (160, 0.1, 8.0, "inverse"), (160, 0.2, 8.0, "inverse"), (160, 0.1, 4.0, "inverse"),
    (160, 0.1, 2.0, "inverse"), (160, 0.1, 8.0, "log"), (160, 0.1, 4.0, "log"), (160, 0.15, 4.0, "log"),
    (240, 0.0, 8.0, "inverse"), (200, 0.1, 4.0, "inverse"), (240, 0.1, 4.0, "inverse"))


def _name(config: Config) -> str:
    levels, confidence, sigma, space = config
    return f"{levels}-{confidence:g}-{sigma:g}-{space}"


def fill_method(levels: int, min_confidence: float, sigma: float, space: str) -> Method:
    """The default method with ``levels`` sphere labels in both its sweep costs, whose sweep refills the pixels below
    ``min_confidence`` (0: none) with an edge scale of ``sigma`` gray levels in ``space``
    (:class:`reconstruction.methods.sweep.PostParams`), everything else the default's; labelled
    ``fused-mirror-<levels>-<confidence>-<sigma>-<space>``."""
    base = fused_mirror()
    sweep = base.sweep
    post = dataclasses.replace(sweep.post, min_confidence=min_confidence, fill_sigma_color=sigma, fill_space=space)
    corrected = None if sweep.corrected_cost is None else dataclasses.replace(sweep.corrected_cost, levels=levels)
    sweep = dataclasses.replace(sweep, post=post, cost=dataclasses.replace(sweep.cost, levels=levels),
                                corrected_cost=corrected)
    return dataclasses.replace(base, sweep=sweep, label=f"{base.label}-{_name((levels, min_confidence, sigma, space))}")


def _same_as_default(method: Method) -> bool:
    mine, default = method.config(), fused_mirror().config()
    return {**mine, "label": None} == {**default, "label": None}


def config_name(config: tuple) -> str:
    """A candidate configuration of numbers as its name in labels and ``--candidates``: the values joined by ``-``
    (``%g``: 2.0 -> ``2``, 0.05 -> ``0.05``)."""
    return "-".join(f"{x:g}" for x in config)


def methods_to_compare(build: Callable[..., Method], reference: tuple, candidates: Sequence[tuple],
                       name: Callable[[tuple], str], names: Sequence[str] | None = None) -> list[Method]:
    """``build(*reference)``, ``build(*config)`` per candidate configuration (``names``: only those whose
    ``name(config)`` is listed; UserError for an unknown one; one configured as the default is left out) and the
    default as registered (left out too when the reference is configured as it: the reference stands for it)."""
    known = {name(c): c for c in candidates}
    unknown = [n for n in (names or ()) if n not in known]
    if unknown:
        raise UserError(f"unknown candidate(s) {', '.join(unknown)} (candidates: {', '.join(known)})")
    chosen = [build(*known[n]) for n in (names if names else known)]
    first = build(*reference)
    default = [] if _same_as_default(first) else [fused_mirror()]
    return [first, *(m for m in chosen if not _same_as_default(m)), *default]


def candidate_methods(names: Sequence[str] | None = None) -> list[Method]:
    """The reference (:data:`REFERENCE`), one :func:`fill_method` per candidate (``names``: these only, as
    ``<levels>-<confidence>-<sigma>-<space>``) and the default (:func:`methods_to_compare`)."""
    return methods_to_compare(fill_method, REFERENCE, CANDIDATES, _name, names)


def region_table(regions: pd.DataFrame, methods: Sequence[str]) -> pd.DataFrame:
    """Method (index) x region (columns, in ``regions``' order): pooled MAE, metres."""
    names = list(dict.fromkeys(regions["region"]))
    table = pd.DataFrame(index=list(methods), columns=names, dtype=float)
    for m in methods:
        mine = regions[regions["method"] == m]
        for r in names:
            table.loc[m, r] = pooled_mae(mine[mine["region"] == r])
    return table


def family_table(results: pd.DataFrame, methods: Sequence[str]) -> pd.DataFrame:
    """(condition, family) (index; ``ideal`` first) x method: pooled MAE, metres; plus a row ``("all", "all")``."""
    results = with_condition(results)
    keys = sorted(set(zip(results["condition"], results["family"], strict=True)), key=lambda k: (k[0] != IDEAL, k))
    index = pd.MultiIndex.from_tuples([*keys, ("all", "all")], names=["condition", "family"])
    table = pd.DataFrame(index=index, columns=list(methods), dtype=float)
    for m in methods:
        mine = results[results["method"] == m]
        for c, f in keys:
            table.loc[(c, f), m] = pooled_mae(mine[(mine["condition"] == c) & (mine["family"] == f)])
        table.loc[("all", "all"), m] = pooled_mae(mine)
    return table


def frame_table(results: pd.DataFrame, methods: Sequence[str]) -> pd.DataFrame:
    """(scene, viewpoint) (index) x method: each frame's MAE, metres."""
    table = results.pivot_table(index=["scene", "viewpoint"], columns="method", values="mae_m", aggfunc="first")
    return table[list(methods)]


def choose(families: pd.DataFrame, candidates: Sequence[str], levels: dict[str, int],
           frames: pd.DataFrame | None = None) -> tuple[str, dict[str, float], dict[str, float]]:
    """The rule of the module doc; ``levels``: each candidate's sphere labels; ``frames``: :func:`frame_table` (the
    reference first; None: no frame bound).  Returns ``(label, worst ratio to the reference over the (condition,
    family) cells per candidate, worst ratio over the frames per candidate)``."""
    cells = families.drop(index=("all", "all"))
    reference = families.columns[0]
    worst = {m: float((cells[m] / cells[reference]).max()) for m in candidates}
    # a frame the reference scores and a candidate does not (no finite MAE) counts as unbounded
    worst_frame = ({m: float((frames[m].fillna(np.inf) / frames[reference]).max()) for m in candidates}
                   if frames is not None else {m: float("nan") for m in candidates})
    eligible = [m for m in candidates if worst[m] <= FAMILY_BOUND and levels[m] <= MAX_LEVELS
                and not worst_frame[m] > FRAME_BOUND]
    pooled = families.loc[("all", "all")]
    best = min([reference, *eligible], key=lambda m: pooled[m])
    return best, worst, worst_frame


def selection_markdown(regions: pd.DataFrame, families: pd.DataFrame, choice: str, worst: dict[str, float],
                       where: str, title: str, worst_frame: dict[str, float] | None = None) -> str:
    """The tables and the choice as Markdown, under ``# <title>, on <where>``."""
    ref = regions.index[0]
    lines = [f"# {title}, on {where}", "",
             "Pooled MAE (m; each frame weighted by its scored pixels) per method and region, and as a multiple "
             f"of {ref}'s:", "", "| method | " + " | ".join(regions.columns) + " |",
             "|---|" + "---:|" * len(regions.columns)]
    for m, row in regions.iterrows():
        lines.append(f"| {m} | " + " | ".join(f"{cell(row[r])} ({row[r] / regions.loc[ref, r]:.3f}x)"
                                             for r in regions.columns) + " |")
    lines += ["", "Pooled MAE (m) per camera condition and room family:", "",
              "| condition | family | " + " | ".join(families.columns) + " |",
              "|---|---|" + "---:|" * len(families.columns)]
    for (c, f), row in families.iterrows():
        lines.append(f"| {c} | {f} | " + " | ".join(cell(x) for x in row) + " |")
    lines += ["", f"Worst (condition, family) ratio to {ref} (eligible at most {FAMILY_BOUND}, and at most "
                  f"{MAX_LEVELS} sphere labels):", ""]
    lines += [f"- {m}: {v:.3f}" for m, v in worst.items()]
    if worst_frame is not None:
        lines += ["", f"Worst frame's ratio to {ref} (eligible at most {FRAME_BOUND}):", ""]
        lines += [f"- {m}: {v:.3f}" for m, v in worst_frame.items()]
    lines += ["", f"Choice (lowest pooled MAE among the eligible and the reference): **{choice}**"]
    return "\n".join(lines) + "\n"


def candidates_main(prog: str, doc: str, argv: Sequence[str] | None, candidates: Callable[..., list[Method]],
                    form: str, names: Sequence[str], title: str) -> int:
    """A selection script's ``main``: ``frames_parser(prog, ...)`` plus ``--candidates`` (names written as ``form``;
    ``names``: all of them), then :func:`select` of ``candidates(chosen names or None)`` under ``title``."""
    parser = frames_parser(prog, doc.splitlines()[0])
    parser.add_argument("--candidates", nargs="+", default=None, metavar="NAME",
                        help=f"candidates as {form} (default: all: " + ", ".join(names) + ")")
    args = parser.parse_args(argv)

    return run_selection(prog, args, lambda ctx: select(args, candidates(args.candidates), ctx, title))


def main(argv: Sequence[str] | None = None) -> int:
    return candidates_main(PROG, __doc__, argv, candidate_methods, "<levels>-<confidence>-<sigma>-<space>",
                           [_name(c) for c in CANDIDATES], TITLE)


def select(args, methods: Sequence[Method], ctx, title: str) -> tuple[str, dict]:
    """Evaluate ``methods`` (the reference first) as ``args`` (:func:`frames_parser`'s) say, on ``ctx``; returns
    ``selection.md``'s text (under ``title``) and ``selection.json``'s payload (the choice of :func:`choose`)."""
    labels = [m.label for m in methods]
    results = evaluate_frames(args.data_root, args.frames, args.out, methods, ctx)
    where = f"{len(results) // len(methods)} frames of {args.data_root}"
    regions = region_table(pd.read_csv(args.out / "regions.csv"), labels)
    families = family_table(results, labels)
    choice, worst, worst_frame = choose(families, labels[1:], {m.label: m.sweep.cost.levels for m in methods},
                                        frame_table(results, labels))
    text = selection_markdown(regions, families, choice, worst, where, title, worst_frame)
    payload = {"where": where, "frames": args.frames, "methods": labels, "choice": choice,
               "worst_family_ratio": worst, "family_bound": FAMILY_BOUND,
               "worst_frame_ratio": worst_frame, "frame_bound": FRAME_BOUND,
               "region_mae_m": {m: {r: float(v) for r, v in row.items()} for m, row in regions.iterrows()},
               "family_mae_m": [{"condition": c, "family": f, **{m: float(x) for m, x in row.items()}}
                                for (c, f), row in families.iterrows()]}
    return text, payload


if __name__ == "__main__":
    sys.exit(startup.run_main(main, PROG))
