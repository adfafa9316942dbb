"""The score command: score predictions on disk (``tri360-pred/1``), from any method, against the ground truth.

Each predictions root becomes a :class:`harness.data.predictions.PredictionMethod`, a
:class:`reconstruction.methods.base.Method` that reads its maps instead of computing them, and goes through exactly
the same path as built-in methods (:func:`harness.commands.evaluate.evaluate`): the same metrics, regions, results
files, config.json and report.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from harness.commands.evaluate import evaluate, select_frames
from harness.data.errors import UserError
from harness.data.names import check_name
from harness.data.predictions import PredictionMethod, prediction_dir, read_method_info
from harness.runtime.context import IN_PROCESS, RunContext
from reconstruction.methods.registry import builtin_methods

__all__ = ["PredictionMethod", "prediction_methods", "score"]  # PredictionMethod: harness.data.predictions


def prediction_methods(pred_roots: Sequence[Path], names: Sequence[str] | None = None) -> list[PredictionMethod]:
    """One :class:`PredictionMethod` per predictions root.

    Every label is an outside name (``--method``, an outside ``method.json``, a folder's name) and is checked with
    :func:`harness.data.names.check_name` before it can become part of a path.

    A ``--method`` name that differs from the root's ``method.json`` name is used and recorded beside it
    (``config()``: ``label_source`` and the method.json); one that is a built-in method's label is refused unless
    the root's method.json names that method: the results would credit a built-in with someone else's predictions.

    Raises:
        UserError: a missing root, a count of names different from the count of roots, duplicate labels, an unsafe
            label (naming where it came from), a built-in label that the method.json contradicts, or a malformed
            method.json.
    """
    roots = [Path(r) for r in pred_roots]
    builtin = {m.label for m in builtin_methods()} if names is not None else set()
    if names is not None and len(names) != len(roots):
        raise UserError(f"--method gives {len(names)} name(s) for {len(roots)} predictions root(s); give one name "
                        "per root, in the same order")
    out = []
    for i, root in enumerate(roots):
        if not root.is_dir():
            raise UserError(f"{root}: predictions root does not exist" if not root.exists()
                            else f"{root}: predictions root is not a directory")
        info = read_method_info(root)
        if names is not None:
            label, source = names[i], "--method"
            if label in builtin and info.get("name") != label:
                held = (f"names method {info['name']!r}" if info.get("name") else "names no method"
                        if (root / "method.json").is_file() else "is missing")
                raise UserError(f"--method {label}: a built-in method's label, but {root / 'method.json'} {held}; "
                                "name these predictions after the method that made them")
        elif info.get("name"):
            label, source = info["name"], f"{root / 'method.json'} (name)"
        else:
            label, source = root.resolve().name, f"{root} (the folder's name, the method's by default; see --method)"
        check_name(label, source)
        out.append(PredictionMethod(label, root.resolve(), info, source))  # absolute: Dask workers may run elsewhere
    labels = [m.label for m in out]
    dup = sorted({x for x in labels if labels.count(x) > 1})
    if dup:
        raise UserError(f"two predictions roots are both named {', '.join(dup)}; name them with --method")
    return out


def _check_complete(methods: Sequence[PredictionMethod], data_root: Path, scenes: Sequence[str] | None) -> None:
    """Every frame under the data root has a prediction in every root (checked before any scoring)."""
    refs = select_frames(data_root, scenes)
    for m in methods:
        missing = [prediction_dir(m.root, r.scene, r.viewpoint) / "distance.exr" for r in refs
                   if not (prediction_dir(m.root, r.scene, r.viewpoint) / "distance.exr").is_file()]
        if missing:
            more = f" (and {len(missing) - 1} more frames)" if len(missing) > 1 else ""
            raise UserError(f"{missing[0]}: file is missing: method {m.label} has no prediction for this frame of "
                            f"{data_root}{more}")


def score(pred_roots: Sequence[Path], data_root: Path, out: Path, names: Sequence[str] | None = None,
          scenes: Sequence[str] | None = None, report: bool = True, ctx: RunContext = IN_PROCESS,
          suite: dict | None = None) -> pd.DataFrame:
    """Score every predictions root against the frames under ``data_root``; write a results set to ``out``.

    ``ctx`` may run the scoring on Dask (one task per frame x predictions root), as in ``evaluate``; ``suite``
    (``harness.commands.parts.suite.score_suite``) is recorded as in ``evaluate``.

    Returns:
        The results table.
    ``out`` is checked like ``evaluate``'s, and must also keep clear of every predictions root.

    Raises:
        UserError: see :func:`prediction_methods`, a frame without a prediction, a malformed prediction (named),
            or anything :func:`harness.commands.evaluate.evaluate` refuses.
    """
    methods = prediction_methods(pred_roots, names)
    _check_complete(methods, data_root, scenes)
    return evaluate(data_root, out, methods, scenes, report=report, ctx=ctx,
                    inputs=[Path(r) for r in pred_roots], suite=suite)
