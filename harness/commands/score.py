"""The score command: score predictions on disk (``tri360-pred/1``), from any method, against the ground truth.

Each predictions root becomes a :class:`harness.data.predictions.PredictionMethod`, a
:class:`reconstruction.methods.base.Method` that reads its maps instead of computing them, and goes through exactly
the same path as built-in methods (:func:`harness.commands.evaluate.evaluate`): the same metrics, regions, results
files, config.json and report.
"""

from __future__ import annotations

import json
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from harness.commands.evaluate import evaluate, select_frames
from harness.data.errors import UserError
from harness.data.layouts import (
    LAYOUTS,
    MANIFEST,
    MANIFEST_FORMAT,
    from_layout,
    from_rectified,
    prediction_candidates,
    read_map,
    turn,
)
from harness.data.names import check_name
from harness.data.outputs import check_output
from harness.data.predictions import PredictionMethod, prediction_dir, read_method_info, write_prediction
from harness.runtime.context import IN_PROCESS, RunContext
from reconstruction.methods.registry import builtin_methods

# PredictionMethod: harness.data.predictions
__all__ = ["PredictionMethod", "prediction_methods", "score", "score_export", "read_manifest", "import_predictions"]


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


# ------------------------------------------------------------------------------ predictions in an export's layout


def read_manifest(export_dir: Path) -> dict:
    """``<export_dir>/manifest.json`` (``tri360-export/1``, written by ``tri360 export``).

    Raises:
        UserError: naming the file: missing, not JSON, another format, an unknown layout.
    """
    path = Path(export_dir) / MANIFEST
    try:
        raw = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise UserError(f"{path}: file is missing (--export must be a directory written by tri360 export)") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise UserError(f"{path}: not a readable export manifest ({exc})") from None
    if not isinstance(raw, dict) or raw.get("format") != MANIFEST_FORMAT or raw.get("layout") not in LAYOUTS \
            or not isinstance(raw.get("frames"), list):
        raise UserError(f"{path}: not a {MANIFEST_FORMAT} manifest of a known layout ({', '.join(LAYOUTS)})")
    return raw


def import_predictions(preds: Path, manifest: dict, refs: Sequence, pred_root: Path) -> None:
    """Convert a method's outputs in the exported layout (``preds``, files named after the exported maps of C:
    :func:`harness.data.layouts.prediction_candidates`) into ``tri360-pred/1`` under ``pred_root``, one frame per
    ``refs`` entry (``scene``, ``viewpoint``), one frame at a time (``pred_root`` is a temporary folder of
    :func:`score_export`, dropped whole on an error).

    Raises:
        UserError: one line naming the culprit: a frame not in the manifest, a missing prediction (the first path
            looked for), an unreadable file or one of another size than the frame.
    """
    layout = LAYOUTS[manifest["layout"]]
    entries = {(e.get("scene"), e.get("viewpoint")): e for e in manifest["frames"] if isinstance(e, dict)}
    for r in refs:
        e = entries.get((r.scene, r.viewpoint))
        if e is None:
            raise UserError(f"{r.path}: frame {r.scene}/{r.viewpoint} is not in the export's manifest")
        fields = {k: str(v) for k, v in e["fields"].items()}
        for k in ("scene", "viewpoint", "split"):  # outside names: checked before they become part of a path
            check_name(fields[k], f"{MANIFEST} ({k})")
        candidates = prediction_candidates(layout, fields)
        found = next(((rel, m, enc) for rel, m, enc in candidates if (Path(preds) / rel).is_file()), None)
        if found is None:
            raise UserError(f"{Path(preds) / candidates[0][0]}: file is missing: no prediction for frame "
                            f"{r.scene}/{r.viewpoint} (looked for {', '.join(c[0] for c in candidates)} under {preds})")
        rel, m, enc = found
        if m.partner:  # a Cassini map of C's pair with m.partner: W rows x H columns, resampled back to C's grid
            values = read_map(Path(preds) / rel, enc, int(e["height"]), int(e["width"]))
            distance = from_rectified(m.quantity, values, m.partner, float(e[f"baseline_{m.partner.lower()}_m"]))
        else:
            values = turn(read_map(Path(preds) / rel, enc, int(e["width"]), int(e["height"])), layout.turned)
            distance = from_layout(m.quantity, values, float(e["baseline_u_m"]))
        if not np.isfinite(distance).any():
            raise UserError(f"{Path(preds) / rel}: no pixel holds a valid prediction (all 0, negative or not finite)")
        write_prediction(pred_root, r.scene, r.viewpoint, distance)


def score_export(preds: Path, export_dir: Path, data_root: Path, out: Path, name: str | None = None,
                 report: bool = True, ctx: RunContext = IN_PROCESS) -> pd.DataFrame:
    """Score a method's outputs written in an export's layout (``tri360 score PREDS --export DIR``).

    The outputs are converted to camera C's distance (:func:`import_predictions`) into a temporary
    ``tri360-pred/1`` root, scored by :func:`score` under the label ``name`` (default: ``preds``' folder name)
    and the temporary root removed.  ``out`` is checked first (never ``preds``, the export or the data root).

    Raises:
        UserError: see :func:`read_manifest`, :func:`import_predictions`, :func:`score`.
    """
    preds, export_dir, data_root = Path(preds), Path(export_dir), Path(data_root)
    if not preds.is_dir():
        raise UserError(f"{preds}: predictions folder does not exist" if not preds.exists()
                        else f"{preds}: predictions folder is not a directory")
    manifest = read_manifest(export_dir)
    label = check_name(name if name is not None else preds.resolve().name,
                       "--method" if name is not None else f"{preds} (the folder's name; see --method)")
    check_output(out, "results", [preds, export_dir, data_root])
    refs = select_frames(data_root)
    with tempfile.TemporaryDirectory(prefix="tri360-import-") as tmp:
        root = Path(tmp) / label
        import_predictions(preds, manifest, refs, root)
        return score([root], data_root, out, [label], report=report, ctx=ctx)
