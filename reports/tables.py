"""Read and validate a results directory; the MAE table (variant x scene, % reduction against ``average``).

A results directory (written by ``tri360 evaluate``) holds ``results.csv`` (one row per scene, viewpoint,
flow, rectify, variant), ``breakdown.csv`` (long format), ``frames.json`` and ``maps/``.  Readers here raise
:class:`harness.data.errors.UserError` with one line naming the file and what is wrong.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd

from harness.data.errors import UserError

__all__ = [
    "RESULT_COLUMNS",
    "BREAKDOWN_COLUMNS",
    "PAPER_MAE_M",
    "PAPER_LABEL",
    "config_key",
    "config_label",
    "config_order",
    "variant_order",
    "load_results",
    "load_breakdown",
    "load_frames",
    "mae_table",
    "mae_markdown",
    "mae_display",
]

KEY_COLUMNS = ["scene", "viewpoint", "flow", "rectify", "variant"]
RESULT_COLUMNS = ["scene", "viewpoint", "width", "height", "flow", "rectify", "variant", "mae_m", "rmse_m",
                  "median_m", "absrel", "delta1", "outlier_rate", "valid_px", "seconds"]
BREAKDOWN_COLUMNS = ["scene", "viewpoint", "flow", "rectify", "variant", "kind", "bin_lo", "bin_hi", "mae_m",
                     "median_m", "n_px"]
_INT_COLUMNS = {"width", "height", "valid_px", "n_px"}

#: The paper's own Fig. 4 figures (mean absolute error, metres; one 1000x500 Blender classroom frame,
#: DeepFlow on plain equirect pairs).  Quoted for reference, never computed by tri360.
PAPER_MAE_M = {"average": 0.14337, "gradient": 0.10906, "color": 0.10902}
PAPER_LABEL = "paper's figures (Fig. 4, quoted; not computed by tri360)"

FLOW_ORDER = ["deepflow", "dis", "farneback", "rlof", "oracle"]
VARIANT_ORDER = ["average", "angle", "gradient", "color"]


def config_key(flow: str, rectify: bool) -> str:
    """Directory name of a configuration under ``maps/``: ``"<flow>-rect"`` or ``"<flow>-plain"``."""
    return f"{flow}-{'rect' if rectify else 'plain'}"


def config_label(flow: str, rectify: bool) -> str:
    """Human label: the key, plus ``" (paper set-up)"`` for DeepFlow on plain (unrectified) pairs."""
    key = config_key(flow, rectify)
    return f"{key} (paper set-up)" if flow == "deepflow" and not rectify else key


def config_order(pairs) -> list[tuple[str, bool]]:
    """Sort (flow, rectify) pairs: flows in :data:`FLOW_ORDER` (paper set-up first), plain before rect."""
    def rank(p):
        flow, rect = p
        return (FLOW_ORDER.index(flow) if flow in FLOW_ORDER else len(FLOW_ORDER), flow, bool(rect))
    return sorted({(str(f), bool(r)) for f, r in pairs}, key=rank)


def variant_order(variants) -> list[str]:
    """Sort variants: ``average, angle, gradient, color`` first, then any others alphabetically."""
    def rank(v):
        return (VARIANT_ORDER.index(v) if v in VARIANT_ORDER else len(VARIANT_ORDER), v)
    return sorted({str(v) for v in variants}, key=rank)


# ------------------------------------------------------------------------------------------------ reading


def _require_dir(results_dir) -> Path:
    d = Path(results_dir)
    if not d.exists():
        raise UserError(f"{d}: results directory does not exist "
                        f"(write one with `tri360 evaluate DATA --out {d}`)")
    if not d.is_dir():
        raise UserError(f"{d}: not a directory (expected a results directory written by `tri360 evaluate`)")
    return d


def _parse_bool(series: pd.Series, path: Path, column: str) -> pd.Series:
    table = {"true": True, "false": False, "1": True, "0": False, "yes": True, "no": False}
    low = series.astype(str).str.strip().str.lower()
    bad = ~low.isin(list(table))
    if bad.any():
        i = int(np.flatnonzero(bad.to_numpy())[0])
        raise UserError(f"{path}: column {column!r} must be true/false, "
                        f"got {series.iloc[i]!r} in data row {i + 1}")
    return low.map(table).astype(bool)


def _parse_numeric(series: pd.Series, path: Path, column: str) -> pd.Series:
    text = series.astype(str).str.strip()
    num = pd.to_numeric(text, errors="coerce")
    missing = text.str.lower().isin(["", "nan"])
    bad = num.isna() & ~missing
    if bad.any():
        i = int(np.flatnonzero(bad.to_numpy())[0])
        raise UserError(f"{path}: column {column!r} must be numeric, "
                        f"got {series.iloc[i]!r} in data row {i + 1}")
    num = num.astype(np.float64)
    if column in _INT_COLUMNS:
        if missing.any():
            i = int(np.flatnonzero(missing.to_numpy())[0])
            raise UserError(f"{path}: column {column!r} is empty in data row {i + 1}")
        if not np.all(np.isfinite(num)) or not np.all(num == np.round(num)):
            raise UserError(f"{path}: column {column!r} must hold whole numbers")
        return num.astype(np.int64)
    return num


def _read_csv(path: Path, columns: list[str], what: str) -> pd.DataFrame:
    if not path.is_file():
        raise UserError(f"{path}: file is missing ({what})")
    try:
        df = pd.read_csv(path, dtype=str, keep_default_na=False)
    except pd.errors.EmptyDataError:
        raise UserError(f"{path}: file is empty "
                        f"(expected a header with columns {', '.join(columns)})") from None
    except (pd.errors.ParserError, UnicodeDecodeError) as exc:
        raise UserError(f"{path}: not a readable CSV file ({str(exc).strip()})") from None
    df.columns = [str(c).strip() for c in df.columns]
    missing = [c for c in columns if c not in df.columns]
    if missing:
        raise UserError(f"{path}: missing column(s) {', '.join(missing)} (found: {', '.join(df.columns)})")
    if df.empty:
        raise UserError(f"{path}: has a header but no data rows")
    df = df[columns].copy()
    for c in columns:
        if c == "rectify":
            df[c] = _parse_bool(df[c], path, c)
        elif c in ("scene", "viewpoint", "flow", "variant", "kind"):
            df[c] = df[c].astype(str).str.strip()
            empty = df[c] == ""
            if empty.any():
                i = int(np.flatnonzero(empty.to_numpy())[0])
                raise UserError(f"{path}: column {c!r} is empty in data row {i + 1}")
        else:
            df[c] = _parse_numeric(df[c], path, c)
    return df


def load_results(results_dir) -> pd.DataFrame:
    """Read and validate ``RESULTS/results.csv``.

    Returns:
        DataFrame with exactly :data:`RESULT_COLUMNS`: strings for names, bool ``rectify``, int sizes and
        ``valid_px``, float metrics (NaN allowed, e.g. for a frame with no scored pixel).
    Raises:
        UserError: missing/empty directory or file, unreadable CSV, missing columns, no rows, non-numeric
            metrics, non-boolean ``rectify``, or duplicate (scene, viewpoint, flow, rectify, variant) rows.
    """
    d = _require_dir(results_dir)
    path = d / "results.csv"
    if not path.is_file() and not any(d.iterdir()):
        raise UserError(f"{d}: results directory is empty (no results.csv; run `tri360 evaluate` first)")
    df = _read_csv(path, RESULT_COLUMNS, "the per-frame results written by `tri360 evaluate`")
    dup = df.duplicated(KEY_COLUMNS, keep=False)
    if dup.any():
        r = df[dup].iloc[0]
        raise UserError(f"{path}: duplicate rows for scene={r.scene} viewpoint={r.viewpoint} flow={r.flow} "
                        f"rectify={r.rectify} variant={r.variant}")
    return df.reset_index(drop=True)


def load_breakdown(results_dir) -> pd.DataFrame | None:
    """Read and validate ``RESULTS/breakdown.csv``; ``None`` if the file does not exist.

    Raises:
        UserError: for an unreadable or malformed file (naming it).
    """
    path = Path(results_dir) / "breakdown.csv"
    if not path.exists():
        return None
    return _read_csv(path, BREAKDOWN_COLUMNS, "the error breakdown written by `tri360 evaluate`")


def load_frames(results_dir) -> list[dict] | None:
    """Read ``RESULTS/frames.json`` -> list of ``{"scene", "viewpoint", "path"}``; ``None`` if absent.

    Raises:
        UserError: if the file is not valid JSON or not a list of objects with those three string keys.
    """
    path = Path(results_dir) / "frames.json"
    if not path.exists():
        return None
    try:
        raw = json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise UserError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(raw, list):
        raise UserError(f"{path}: must be a JSON list of {{scene, viewpoint, path}} objects")
    out = []
    for i, item in enumerate(raw):
        if not isinstance(item, dict) or not all(isinstance(item.get(k), str) for k in ("scene", "viewpoint",
                                                                                        "path")):
            raise UserError(f"{path}: entry {i} must be an object with string keys scene, viewpoint, path")
        out.append({"scene": item["scene"], "viewpoint": item["viewpoint"], "path": item["path"]})
    return out


# ---------------------------------------------------------------------------------------------- MAE table


def _reduction_pct(avg: float, value: float) -> float:
    if not (math.isfinite(avg) and math.isfinite(value)) or avg <= 0:
        return float("nan")
    return 100.0 * (avg - value) / avg


def mae_table(results: pd.DataFrame) -> pd.DataFrame:
    """The MAE table: one row per (configuration, variant), then the paper's reference rows.

    For every scene, ``<scene> mae_m`` is the mean of the per-frame ``mae_m`` over that scene's frames
    (viewpoints); ``all mae_m`` is the mean over every frame.  ``... reduction_pct`` is
    ``100 * (MAE_average - MAE_variant) / MAE_average`` with ``average`` of the same flow/rectify
    configuration averaged over the *same* frames as the variant (positive = better than ``average``);
    empty for ``average`` itself and where ``average`` is missing.

    Returns:
        DataFrame with columns ``source`` ("tri360" or "paper"), ``configuration`` (label), ``flow``,
        ``rectify``, ``variant``, then ``<scene> mae_m, <scene> reduction_pct`` per scene (sorted),
        ``all mae_m, all reduction_pct`` and ``frames`` (number of frames averaged).
    """
    scenes = sorted(results["scene"].unique())
    rows = []
    for flow, rect in config_order(zip(results["flow"], results["rectify"], strict=True)):
        conf = results[(results["flow"] == flow) & (results["rectify"] == rect)]
        avg = conf[conf["variant"] == "average"].set_index(["scene", "viewpoint"])["mae_m"]
        for variant in variant_order(conf["variant"]):
            sub = conf[conf["variant"] == variant]
            row = {"source": "tri360", "configuration": config_label(flow, rect), "flow": flow,
                   "rectify": rect, "variant": variant}
            for scene, part in [*((s, sub[sub["scene"] == s]) for s in scenes), ("all", sub)]:
                mae = float(part["mae_m"].mean()) if len(part) else float("nan")
                keys = list(zip(part["scene"], part["viewpoint"], strict=True))
                paired = avg.reindex(keys)
                red = float("nan")
                if variant != "average" and len(part) and paired.notna().all():
                    red = _reduction_pct(float(paired.mean()), mae)
                row[f"{scene} mae_m"] = mae
                row[f"{scene} reduction_pct"] = red
            row["frames"] = len(sub)
            rows.append(row)
    for variant, mae in PAPER_MAE_M.items():
        row = {"source": "paper", "configuration": PAPER_LABEL, "flow": "deepflow", "rectify": False,
               "variant": variant}
        for scene in scenes:
            row[f"{scene} mae_m"] = float("nan")
            row[f"{scene} reduction_pct"] = float("nan")
        row["all mae_m"] = mae
        row["all reduction_pct"] = (float("nan") if variant == "average"
                                    else _reduction_pct(PAPER_MAE_M["average"], mae))
        row["frames"] = 1
        rows.append(row)
    return pd.DataFrame(rows)


def mae_display(table: pd.DataFrame) -> pd.DataFrame:
    """String version of :func:`mae_table` for markdown/HTML: MAE to 5 decimals (m), reductions in %."""
    scene_cols = [c[: -len(" mae_m")] for c in table.columns if c.endswith(" mae_m")]
    out = pd.DataFrame({"configuration": table["configuration"], "variant": table["variant"]})
    for s in scene_cols:
        name = "all frames" if s == "all" else s
        out[f"{name} MAE (m)"] = [("—" if not math.isfinite(v) else f"{v:.5f}") for v in table[f"{s} mae_m"]]
        out[f"{name} vs average"] = [("—" if not math.isfinite(v) else f"{v:+.2f} %")
                                     for v in table[f"{s} reduction_pct"]]
    out["frames"] = table["frames"].astype(int).astype(str)
    return out.reset_index(drop=True)


def _md_cell(text: str) -> str:
    return str(text).replace("|", "\\|")


def mae_markdown(table: pd.DataFrame) -> str:
    """Markdown document with the MAE table (from :func:`mae_table`) and how to read it."""
    disp = mae_display(table)
    lines = [
        "# Mean absolute error of camera C's distance",
        "",
        "MAE in metres, mean over frames (viewpoints) of each frame's MAE.",
        "\"vs average\" is the reduction against the `average` variant (the paper's \"before optimisation\")",
        "of the same flow/rectify configuration on the same frames:",
        "100 * (MAE_average - MAE_variant) / MAE_average, positive = better.",
        "Pixels with no surface are not scored; a missing or invalid prediction counts with",
        "error = true distance.",
        "The last three rows are the paper's own Fig. 4 numbers (one 1000x500 Blender classroom frame,",
        "DeepFlow on plain equirect pairs), quoted, not computed by tri360; their reductions are computed",
        "here from those MAEs (the paper's text quotes 23.93 % and 23.95 %).",
        "",
        "| " + " | ".join(_md_cell(c) for c in disp.columns) + " |",
        "|" + "|".join("---" if i < 2 else "---:" for i in range(len(disp.columns))) + "|",
    ]
    for _, r in disp.iterrows():
        lines.append("| " + " | ".join(_md_cell(v) for v in r) + " |")
    return "\n".join(lines) + "\n"
