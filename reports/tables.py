"""The results tables: the MAE table of the flow pipeline (variant x scene, % reduction against ``average``), the
leaderboard (every method x overall metrics and MAE per region) and the floor per region with every method's MAE as a
multiple of it (``reports.floor``), with their markdown and display forms.

Pure: validated results DataFrames in (``harness.data.results`` reads them from a results directory with the
columns of :mod:`reports.schema`), DataFrames and text out.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from reconstruction.methods.flow_pipeline import config_label
from reconstruction.methods.registry import PAPER_CONFIG
from reconstruction.quality import CALIBRATION_THRESHOLD
from reports.floor import FLOOR_PX, times_floor
from reports.regions import REGION_NAMES
from reports.schema import QUALITY_COLUMNS, unscored_rows

__all__ = [
    "suite_text",
    "PAPER_MAE_M",
    "PAPER_LABEL",
    "PAPER_FAMILY",
    "paper_scene_rows",
    "config_title",
    "config_order",
    "variant_order",
    "method_order",
    "variant_mae_table",
    "SUMMARY_METRICS",
    "method_summary",
    "mae_markdown",
    "mae_display",
    "LEADERBOARD_OVERALL",
    "LEADERBOARD_REGIONS",
    "pixel_weighted",
    "leaderboard_table",
    "leaderboard_display",
    "leaderboard_markdown",
    "FLOOR_ROW",
    "FLOOR_TEXT",
    "floor_region_table",
    "floor_region_display",
    "NOTHING_SCORED",
    "QUALITY_HEADERS",
    "quality_table",
    "quality_summary",
    "quality_markdown",
]


#: The paper's own Fig. 4 figures (mean absolute error, metres; one 1000x500 Blender classroom frame of theirs,
#: DeepFlow).  Quoted for reference, never computed by tri360.
PAPER_MAE_M = {"average": 0.14337, "gradient": 0.10906, "color": 0.10902}
PAPER_LABEL = "paper's figures (Fig. 4, quoted; not computed by tri360)"
#: the scene family of the paper's Fig. 4 frame
PAPER_FAMILY = "classroom"

FLOW_ORDER = ["deepflow", "deepflow-opencv", "dis", "farneback", "rlof", "oracle"]
VARIANT_ORDER = ["average", "angle", "gradient", "color"]


def config_title(flow: str, rectify: bool) -> str:
    """Human title of a flow configuration: its label (``reconstruction.methods.flow_pipeline.config_label``,
    e.g. ``dis-rect``), plus ``" (paper set-up)"`` for the paper's set-up
    (``reconstruction.methods.registry.PAPER_CONFIG``: ``deepflow-rect``)."""
    label = config_label(flow, bool(rectify))
    return f"{label} (paper set-up)" if (flow, bool(rectify)) == PAPER_CONFIG else label


def paper_scene_rows(results: pd.DataFrame) -> pd.Series:
    """Rows of frames of the paper's scene (:data:`PAPER_FAMILY`, the classroom): by the ``family`` column where a
    row names one, else by the scene name."""
    scene = results["scene"].astype(str) == PAPER_FAMILY
    if "family" not in results.columns:
        return scene
    family = results["family"].fillna("").astype(str)
    return (family == PAPER_FAMILY) | ((family == "") & scene)


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


def method_order(results: pd.DataFrame) -> list[str]:
    """Method labels in display order: flow-pipeline methods by :func:`config_order` then :func:`variant_order`,
    then every other method alphabetically."""
    flow_rows = results[results["flow"] != ""]
    out = []
    for flow, rect in config_order(zip(flow_rows["flow"], flow_rows["rectify"], strict=True)):
        conf = flow_rows[(flow_rows["flow"] == flow) & (flow_rows["rectify"] == rect)]
        for variant in variant_order(conf["variant"]):
            out.extend(sorted(set(conf.loc[conf["variant"] == variant, "method"])))
    out.extend(sorted(set(results.loc[results["flow"] == "", "method"]) - set(out)))
    return out


#: the metrics of :func:`method_summary`, each the mean over a method's frames
SUMMARY_METRICS = ("mae_m", "mae_x_floor", "median_m", "delta110", "seconds")


def method_summary(results: pd.DataFrame) -> pd.DataFrame:
    """One row per method, best first: the mean over its frames of MAE (m), of the MAE as a multiple of the frame's
    floor (``mae_x_floor``: the mean of the per-frame ratios, as the MAE is the mean of the per-frame MAEs; 1 = an
    ideal matcher, ``reports.floor``), of the median absolute error (m), of the share of pixels with
    ``max(pred/gt, gt/pred) < 1.10`` (``delta110``, 0..1) and of its wall time per frame (s).

    Args:
        results: a results table (``RESULT_COLUMNS``; a metric column it lacks reads as NaN).
    Returns:
        DataFrame with columns ``method, frames`` and :data:`SUMMARY_METRICS`, sorted by ``mae_m`` (NaN last),
        then by method label.  A mean is NaN when any of its frames' values is (never silently dropped).
    """
    t = results.assign(**{c: np.nan for c in SUMMARY_METRICS if c not in results.columns})
    grouped = t.groupby("method", sort=True)
    out = pd.DataFrame({"frames": grouped.size()})
    for c in SUMMARY_METRICS:
        out[c] = grouped[c].agg(lambda s: float(pd.to_numeric(s, errors="coerce").mean(skipna=False)))
    out = out.reset_index().sort_values(["mae_m", "method"], na_position="last", kind="stable")
    return out.reset_index(drop=True)[["method", "frames", *SUMMARY_METRICS]]


# ---------------------------------------------------------------------------------------------- MAE table


def _reduction_pct(avg: float, value: float) -> float:
    if not (math.isfinite(avg) and math.isfinite(value)) or avg <= 0:
        return float("nan")
    return 100.0 * (avg - value) / avg


def variant_mae_table(results: pd.DataFrame) -> pd.DataFrame:
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
            row = {"source": "tri360", "configuration": config_title(flow, rect), "flow": flow,
                   "rectify": rect, "variant": variant}
            for scene, part in [*((s, sub[sub["scene"] == s]) for s in scenes), ("all", sub)]:
                mae = float(part["mae_m"].mean(skipna=False)) if len(part) else float("nan")
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
        row = {"source": "paper", "configuration": PAPER_LABEL, "flow": PAPER_CONFIG[0], "rectify": PAPER_CONFIG[1],
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
    """String version of :func:`variant_mae_table` for markdown/HTML: MAE to 5 decimals (m), reductions in %."""
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
    """Markdown document with the MAE table (from :func:`variant_mae_table`) and how to read it."""
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
        "DeepFlow), quoted, not computed by tri360; their reductions are computed",
        "here from those MAEs (the paper's text quotes 23.93 % and 23.95 %).",
        "",
        "| " + " | ".join(_md_cell(c) for c in disp.columns) + " |",
        "|" + "|".join("---" if i < 2 else "---:" for i in range(len(disp.columns))) + "|",
    ]
    for _, r in disp.iterrows():
        lines.append("| " + " | ".join(_md_cell(v) for v in r) + " |")
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------------------------- leaderboard


#: overall columns of the leaderboard: (results.csv column, which way is better: "low" or "high"; "ref" for a
#: reference that is not the method's merit: the floor of its frames)
LEADERBOARD_OVERALL = (("mae_m", "low"), ("mae_x_floor", "low"), ("floor_m", "ref"), ("mae_sw_m", "low"),
                       ("median_m", "low"), ("median_sw_m", "low"), ("p90_m", "low"), ("bad_5pct", "low"),
                       ("delta110", "high"), ("coverage", "high"), ("ause", "low"))
#: leaderboard columns that are the ratio of two pooled columns (numerator, denominator), not pooled themselves
RATIO_COLUMNS = {"mae_x_floor": ("mae_m", "floor_m")}
#: solid-angle-weighted columns: pooled over frames by the scored pixels' solid angle (``valid_sr``), not their count
SOLID_ANGLE_COLUMNS = {"mae_sw_m", "median_sw_m"}
#: prefixes of the per-family and per-difficulty-tag MAE columns (plain and solid-angle weighted)
FAMILY_PREFIX, TAG_PREFIX = "mae_family:", "mae_tag:"
FAMILY_SW_PREFIX, TAG_SW_PREFIX = "mae_sw_family:", "mae_sw_tag:"
#: the "family" of every frame in a leaderboard whose frames come under several conditions (``all@captured``)
ALL_FAMILIES = "all"
#: regions with an MAE column of their own (``all`` is ``mae_m``)
LEADERBOARD_REGIONS = tuple(r for r in REGION_NAMES if r != "all")
#: leaderboard columns shown as percentages (shares 0..1 in leaderboard.csv)
SHARE_COLUMNS = {"bad_5pct", "delta110", "coverage"}
LEADERBOARD_HEADERS = {"method": "method", "kind": "kind", "frames": "frames", "mae_m": "MAE (m)",
                       "mae_x_floor": "MAE (× floor)", "floor_m": "floor (m)",
                       "mae_sw_m": "MAE, solid-angle weighted (m)", "median_sw_m": "median, solid-angle weighted (m)",
                       "median_m": "median (m)", "p90_m": "p90 (m)", "bad_5pct": "bad 5 % (%)",
                       "delta110": "δ < 1.10 (%)", "coverage": "coverage (%)", "ause": "AUSE (m)"}
PAPER_KIND = "quoted from the paper"


def pixel_weighted(values, weights) -> float:
    """``sum(v * w) / sum(w)`` over the entries with ``w > 0`` (frames with no scored pixel carry no weight).

    NaN if a weighted entry is NaN (a missing metric is never silently dropped) or if no entry has weight.
    """
    v = np.asarray(values, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    keep = w > 0
    if not keep.any() or np.isnan(v[keep]).any():
        return float("nan")
    return float(np.sum(v[keep] * w[keep]) / np.sum(w[keep]))


def _groups(results: pd.DataFrame) -> list[tuple[str, str, pd.Series]]:
    """``(plain column, weighted column, row mask)`` for every family and every difficulty tag in ``results``
    (families in order of appearance, then tags in order of appearance).  When the frames come under more than one
    condition (column ``condition``: ``ideal`` and ``captured``), every frame under each condition
    (``all@<condition>``) and each family under each condition (``<family>@<condition>``) instead of the families."""
    if "family" not in results.columns:
        return []
    fam = results["family"].fillna("").astype(str)
    tags = results["tags"].fillna("").astype(str).str.split(";") if "tags" in results.columns else None
    cond = results["condition"].fillna("").astype(str) if "condition" in results.columns else None
    conditions = [c for c in dict.fromkeys(cond) if c] if cond is not None else []
    if len(conditions) > 1:  # each family under each condition, after every frame under each condition
        out = [(FAMILY_PREFIX + f"{ALL_FAMILIES}@{c}", FAMILY_SW_PREFIX + f"{ALL_FAMILIES}@{c}", cond == c)
               for c in conditions]
        out += [(FAMILY_PREFIX + f"{f}@{c}", FAMILY_SW_PREFIX + f"{f}@{c}", (fam == f) & (cond == c))
                for f in dict.fromkeys(fam) if f for c in conditions]
    else:
        out = [(FAMILY_PREFIX + f, FAMILY_SW_PREFIX + f, fam == f) for f in dict.fromkeys(fam) if f]
    if tags is not None:
        names = dict.fromkeys(t for ts in tags for t in ts if t)
        out += [(TAG_PREFIX + t, TAG_SW_PREFIX + t, tags.map(lambda ts, t=t: t in ts).astype(bool)) for t in names]
    return out


def leaderboard_table(results: pd.DataFrame, regions: pd.DataFrame | None = None,
                      kinds: dict[str, str] | None = None) -> pd.DataFrame:
    """Every method of a results set against the overall metrics and the MAE per region, plus the paper's rows.

    Every number is pooled over the method's frames with each frame weighted by its number of scored pixels
    (``valid_px``; per region: the region's scored pixels in that frame): ``sum_f value_f N_f / sum_f N_f``.  For
    the means and shares (``mae_m``, the region MAEs, ``bad_5pct``, ``delta110``, ``coverage``) this *is* the value
    over all scored pixels of all frames together; for ``median_m``, ``p90_m`` and ``ause`` it is the
    pixel-weighted mean of the per-frame values (a percentile of the pooled pixels would need the maps).  With
    one frame per method every number is that frame's.  A NaN of any frame gives NaN (e.g. ``ause`` of a method
    without confidence).  The solid-angle-weighted columns (``mae_sw_m``, ``median_sw_m``: each pixel weighted by
    cos latitude) pool with each frame weighted by its scored pixels' solid angle (``valid_sr``) instead.
    ``floor_m`` is the floor of the method's frames pooled the same way (the MAE an ideal matcher makes over the
    same pixels, ``reports.floor``), and ``mae_x_floor`` the pooled ``mae_m`` divided by it (:data:`RATIO_COLUMNS`:
    a ratio of the pooled values, not a pooled ratio; NaN for results without the floor).

    When the rows name their family and difficulty tags (``family``, ``tags``), ``mae_family:<family>`` and
    ``mae_tag:<tag>`` (then ``mae_sw_family:...``, ``mae_sw_tag:...``, solid-angle weighted) pool the MAE over the
    frames of that family or tag (NaN where the method has none); rows of several conditions (``condition``) give
    ``mae_family:all@<condition>`` and ``mae_family:<family>@<condition>`` instead of the family columns;
    ``suite_id`` and ``split`` name the suite split
    the results were measured on (empty outside a suite; "mixed" if the rows disagree).

    Args:
        results: validated ``results.csv`` (``harness.data.results.read_results``).
        regions: validated ``regions.csv`` (``harness.data.results.read_regions``) or None (region columns all NaN).
        kinds: method label -> kind from ``config.json`` (``harness.data.results.read_method_kinds``).
    Returns:
        DataFrame, columns ``source`` ("tri360" / "paper"), ``method``, ``kind``, ``flow``, ``rectify``,
        ``variant``, ``frames``, ``suite_id``, ``split``, the :data:`LEADERBOARD_OVERALL` columns (metres / shares
        0..1), the family and tag columns (metres) and ``mae_<region>`` for each of :data:`LEADERBOARD_REGIONS`
        (metres).  tri360 rows sorted by ``mae_m``
        (NaN last), then one row per :data:`PAPER_MAE_M` entry, labelled ``paper: deepflow-rect:<variant>`` (MAE
        only; every other number NaN).
    """
    kinds = kinds or {}
    rows = []
    groups = _groups(results)
    suite = {}
    for col in ("suite_id", "split"):
        values = set(results[col].fillna("").astype(str)) if col in results.columns else {""}
        suite[col] = values.pop() if len(values) == 1 else "mixed"
    for label in method_order(results):
        sel = results["method"] == label
        sub = results[sel]
        first = sub.iloc[0]
        row = {"source": "tri360", "method": label,
               "kind": kinds.get(label) or ("flow-pipeline" if first["flow"] else ""),
               "flow": first["flow"], "rectify": first["rectify"], "variant": first["variant"], "frames": len(sub),
               **suite}
        for col, _ in LEADERBOARD_OVERALL:
            weight = "valid_sr" if col in SOLID_ANGLE_COLUMNS else "valid_px"
            row[col] = (pixel_weighted(sub[col], sub[weight]) if col in sub.columns and weight in sub.columns
                        else float("nan"))
        for col, (num, den) in RATIO_COLUMNS.items():
            row[col] = times_floor(row[num], row[den])
        for plain, weighted, mask in groups:
            part = results[sel & mask]
            row[plain] = pixel_weighted(part["mae_m"], part["valid_px"]) if len(part) else float("nan")
            row[weighted] = (pixel_weighted(part["mae_sw_m"], part["valid_sr"])
                             if len(part) and "valid_sr" in part.columns else float("nan"))
        for region in LEADERBOARD_REGIONS:
            part = None if regions is None else regions[(regions["method"] == label) & (regions["region"] == region)]
            row[f"mae_{region}"] = (float("nan") if part is None or part.empty
                                    else pixel_weighted(part["mae_m"], part["valid_px"]))
        rows.append(row)
    table = pd.DataFrame(rows)
    if len(table):
        table = table.sort_values("mae_m", kind="stable", na_position="last")
    paper = []
    for variant, mae in PAPER_MAE_M.items():
        row = {"source": "paper", "method": f"paper: {config_label(*PAPER_CONFIG)}:{variant}",
               "kind": PAPER_KIND, "flow": PAPER_CONFIG[0], "rectify": PAPER_CONFIG[1], "variant": variant, "frames": 1,
               "suite_id": "", "split": ""}
        row.update({col: float("nan") for col, _ in LEADERBOARD_OVERALL})
        row.update({c: float("nan") for plain, weighted, _ in groups for c in (plain, weighted)})
        row.update({f"mae_{r}": float("nan") for r in LEADERBOARD_REGIONS})
        row["mae_m"] = mae
        paper.append(row)
    return pd.concat([table, pd.DataFrame(paper)], ignore_index=True)


def group_columns(table: pd.DataFrame) -> list[str]:
    """The per-family and per-tag MAE columns of a leaderboard table, plain ones first, in table order."""
    cols = [str(c) for c in table.columns]
    return ([c for c in cols if c.startswith((FAMILY_PREFIX, TAG_PREFIX))]
            + [c for c in cols if c.startswith((FAMILY_SW_PREFIX, TAG_SW_PREFIX))])


def _group_header(col: str) -> str:
    for prefix, what in ((FAMILY_PREFIX, ""), (TAG_PREFIX, "tag "), (FAMILY_SW_PREFIX, "sw "),
                         (TAG_SW_PREFIX, "sw tag ")):
        if col.startswith(prefix):
            name = col[len(prefix):]
            return what + (name.replace("_", " ") if "tag" in what else name)
    return col


def _metric_columns(table: pd.DataFrame | None = None) -> list[tuple[str, str]]:
    groups = [] if table is None else [(c, "low") for c in group_columns(table)]
    return [*LEADERBOARD_OVERALL, *groups, *((f"mae_{r}", "low") for r in LEADERBOARD_REGIONS)]


def _fmt(col: str, v: float) -> str:
    if not math.isfinite(v):
        return "—"
    if col in RATIO_COLUMNS:
        return f"{v:.2f}"
    return f"{100 * v:.2f}" if col in SHARE_COLUMNS else f"{v:.5f}"


def leaderboard_display(table: pd.DataFrame) -> dict:
    """What the HTML leaderboard shows, from :func:`leaderboard_table`.

    Returns:
        dict with ``display`` (DataFrame of strings: method, kind, frames, the overall columns (metres to 5
        decimals, shares in %) and one MAE column per region), ``columns`` (the leaderboard column behind each
        displayed one), ``keys`` (per row, per column: the sort key, float or str; None for a missing number),
        ``better`` (per column "low", "high", "ref" for a reference number (the floor) or "" for text), ``best``
        ((rows, cols) bool: the best value of each "low" / "high" column among tri360's rows, ties included within
        1e-9 relative) and ``row_classes`` ("paper" for the quoted rows).
    """
    metric_cols = _metric_columns(table)
    columns = ["method", "kind", "frames", *(c for c, _ in metric_cols)]
    better = ["", "", "", *(b for _, b in metric_cols)]
    disp = pd.DataFrame({"method": table["method"].astype(str),
                         "kind": [k if k else "—" for k in table["kind"].astype(str)],
                         "frames": table["frames"].astype(int).astype(str)})
    for col, _ in metric_cols:
        header = LEADERBOARD_HEADERS.get(col) or (_group_header(col) if ":" in col else col.removeprefix("mae_"))
        disp[header] = [_fmt(col, float(v)) for v in table[col]]
    keys = []
    for _, r in table.iterrows():
        keys.append([r["method"], r["kind"], int(r["frames"]),
                     *((float(r[c]) if math.isfinite(float(r[c])) else None) for c, _ in metric_cols)])
    best = np.zeros((len(table), len(columns)), dtype=bool)
    ours = (table["source"] == "tri360").to_numpy()
    for j, (col, way) in enumerate(metric_cols, start=3):
        if way not in ("low", "high"):
            continue
        v = table[col].to_numpy(dtype=np.float64)
        ok = ours & np.isfinite(v)
        if ok.any():
            b = v[ok].min() if way == "low" else v[ok].max()
            best[:, j] = ok & (np.abs(v - b) <= 1e-12 + 1e-9 * abs(b))
    return {"display": disp, "columns": columns, "keys": keys, "better": better, "best": best,
            "row_classes": ["paper" if s == "paper" else "" for s in table["source"]]}


#: the label of the floor's row in :func:`floor_region_table`
FLOOR_ROW = "floor (m)"
#: what the floor is, in one sentence of the report
FLOOR_TEXT = (f"The floor is the MAE an ideal matcher would make over the same pixels: {FLOOR_PX:g} px angular error "
              "per pair (Gaussian), pairs combined by inverse variance, computed from the true distance and the rig "
              "(docs/metrics.md, \"The floor\").")


def floor_region_table(results: pd.DataFrame, regions: pd.DataFrame | None = None,
                       methods: list[str] | None = None) -> pd.DataFrame:
    """The floor and every method's MAE as a multiple of it, over all scored pixels and per region.

    Args:
        results: validated ``results.csv`` (its ``floor_m`` per frame: ``reports.schema.FLOOR_COLUMNS``; NaN or
            absent: no floor).
        regions: validated ``regions.csv`` or None (region columns NaN).
        methods: the method rows, in order (default :func:`method_order`).
    Returns:
        DataFrame with columns ``method``, ``all`` and each of :data:`LEADERBOARD_REGIONS`.  First row
        (``method`` = :data:`FLOOR_ROW`): the floor in metres, pooled over every frame of the results (each frame
        once, weighted by its scored pixels in the region, as the leaderboard pools).  Then one row per method: its
        MAE pooled over its frames divided by the floor pooled over the same frames (unitless; 1 = the ideal
        matcher), NaN where either is missing.
    """
    cols = ["all", *LEADERBOARD_REGIONS]
    methods = method_order(results) if methods is None else list(methods)
    parts = {"all": results.assign(region="all")}
    if regions is not None:
        parts.update({r: regions[regions["region"] == r] for r in LEADERBOARD_REGIONS})

    def pooled(part: pd.DataFrame | None, col: str) -> float:
        if part is None or part.empty or col not in part.columns:
            return float("nan")
        return pixel_weighted(part[col], part["valid_px"])

    floor_row = {"method": FLOOR_ROW}
    for c in cols:
        part = parts.get(c)
        # the floor is the frame's, the same in every method's row: each frame once (a row with its pixels)
        frames = (None if part is None else
                  part.sort_values("valid_px", ascending=False, kind="stable").drop_duplicates(["scene", "viewpoint"]))
        floor_row[c] = pooled(frames, "floor_m")
    rows = [floor_row]
    for label in methods:
        row = {"method": label}
        for c in cols:
            part = parts.get(c)
            mine = None if part is None else part[part["method"] == label]
            row[c] = times_floor(pooled(mine, "mae_m"), pooled(mine, "floor_m"))
        rows.append(row)
    return pd.DataFrame(rows, columns=["method", *cols])


def floor_region_display(table: pd.DataFrame) -> pd.DataFrame:
    """:func:`floor_region_table` as strings: the floor in metres (5 decimals), the multiples to 2 decimals, "—"
    where there is no value."""
    out = table.copy().astype(object)
    for c in table.columns[1:]:
        out[c] = [_fmt("floor_m" if m == FLOOR_ROW else "mae_x_floor", float(v))
                  for m, v in zip(table["method"], table[c], strict=True)]
    return out


def leaderboard_markdown(table: pd.DataFrame, floors: pd.DataFrame | None = None) -> str:
    """Markdown document with the leaderboard (from :func:`leaderboard_table`): overall metrics, then MAE per
    region, then (with ``floors``, :func:`floor_region_table`) the floor and the MAE as a multiple of it per region;
    the paper's quoted rows are marked."""
    overall = [c for c, _ in LEADERBOARD_OVERALL]
    lines = [
        "# Leaderboard: camera C's distance, every method",
        "",
        "Pooled over each method's frames, each frame weighted by its scored pixels: exact over all pixels for",
        "MAE and the shares; the pixel-weighted mean of the per-frame values for median, p90 and AUSE.",
        FLOOR_TEXT,
        "MAE (× floor) is the pooled MAE divided by the pooled floor of the same frames.",
        "Shares in %; lower is better except for δ < 1.10 and coverage.  A missing or invalid prediction",
        "counts with error = true distance.  Rows of kind \"quoted from the paper\" are the paper's own Fig. 4 MAEs",
        "(one 1000x500 classroom frame of theirs, DeepFlow), not computed by tri360.",
        "Columns marked \"solid-angle weighted\" weight every pixel by the solid angle it covers (cos latitude,",
        "as Pano3D recommends: equirect pixels near the poles cover less of the sphere) and pool frames by their",
        "scored solid angle; every other column weighs each pixel the same.",
        "",
        *_suite_lines(table),
        "| method | kind | frames | " + " | ".join(LEADERBOARD_HEADERS[c] for c in overall) + " |",
        "|---|---|---:|" + "---:|" * len(overall),
    ]
    for _, r in table.iterrows():
        cells = [r["method"], r["kind"] or "—", str(int(r["frames"])), *(_fmt(c, float(r[c])) for c in overall)]
        lines.append("| " + " | ".join(_md_cell(x) for x in cells) + " |")
    lines += ["", "## MAE per region (m)", "",
              "Regions: docs/metrics.md (`reports.regions`).", "",
              "| method | " + " | ".join(LEADERBOARD_REGIONS) + " |",
              "|---|" + "---:|" * len(LEADERBOARD_REGIONS)]
    for _, r in table[table["source"] == "tri360"].iterrows():
        cells = [r["method"], *(_fmt("mae_m", float(r[f"mae_{g}"])) for g in LEADERBOARD_REGIONS)]
        lines.append("| " + " | ".join(_md_cell(x) for x in cells) + " |")
    groups = group_columns(table)
    for title, cols in (("MAE per family and difficulty tag (m)",
                         [c for c in groups if c.startswith((FAMILY_PREFIX, TAG_PREFIX))]),
                        ("MAE per family and difficulty tag, solid-angle weighted (m)",
                         [c for c in groups if c.startswith((FAMILY_SW_PREFIX, TAG_SW_PREFIX))])):
        if not cols:
            continue
        lines += ["", f"## {title}", "",
                  "Pooled over the frames of each scene family, and of each difficulty tag (a frame counts for every "
                  "tag it carries); — where the method has no such frame.", "",
                  "| method | " + " | ".join(_group_header(c).removeprefix("sw ") for c in cols) + " |",
                  "|---|" + "---:|" * len(cols)]
        for _, r in table[table["source"] == "tri360"].iterrows():
            cells = [r["method"], *(_fmt("mae_m", float(r[c])) for c in cols)]
            lines.append("| " + " | ".join(_md_cell(x) for x in cells) + " |")
    if floors is not None:
        disp = floor_region_display(floors)
        lines += ["", "## The floor and the MAE as a multiple of it, per region", "",
                  f"First row: the floor in metres. {FLOOR_TEXT} Then each method's MAE divided by the floor of the "
                  "same pixels (1 = the ideal matcher).", "",
                  "| method | " + " | ".join(str(c) for c in disp.columns[1:]) + " |",
                  "|---|" + "---:|" * (len(disp.columns) - 1)]
        for _, r in disp.iterrows():
            lines.append("| " + " | ".join(_md_cell(x) for x in r) + " |")
    return "\n".join(lines) + "\n"


def suite_text(table: pd.DataFrame) -> str:
    """The sentence naming the suite split a leaderboard was measured on ("" outside a suite)."""
    if "suite_id" not in table.columns:
        return ""
    ours = table[table["source"] == "tri360"]
    ids = sorted({str(x) for x in ours["suite_id"]} - {""})
    splits = sorted({str(x) for x in ours["split"]} - {""})
    if not ids:
        return ""
    return (f"Measured on suite {', '.join(ids)}, split {', '.join(splits) or '?'} (the suite id names the exact "
            "frames: docs/suites.md).")


def _suite_lines(table: pd.DataFrame) -> list[str]:
    """The leaderboard markdown's suite line and a blank line (none outside a suite)."""
    text = suite_text(table)
    return [text, ""] if text else []


# ------------------------------------------------------------------------------- frames without ground truth


#: what every report part on frames without ground truth says first
NOTHING_SCORED = "no ground truth: nothing scored"
#: headings of :data:`reports.schema.QUALITY_COLUMNS` (``reconstruction.quality``; docs/real-captures.md)
QUALITY_HEADERS = {
    "photometric_residual_median": "photometric residual (grey levels)",
    "distance_residual_m_median": "distance residual (m)",
    "pair_agreement_median": "pair disagreement |log(d_U/d_R)|",
    "uncertainty_median": "uncertainty",
    "calibration_score": "calibration score",
}


def quality_table(results: pd.DataFrame) -> pd.DataFrame:
    """The ground-truth-free quality figures of the rows that scored nothing (``reports.schema.unscored_rows``:
    frames without ground truth), one row per frame and method.

    Args:
        results: a results table (rows of scored frames, if any, are left out).
    Returns:
        DataFrame with ``scene, viewpoint, method``, the :data:`reports.schema.QUALITY_COLUMNS` (medians over the
        validly predicted pixels; the calibration score), ``calibration_flagged`` (score above
        ``reconstruction.quality.CALIBRATION_THRESHOLD``) and ``seconds``, sorted by frame, then
        :func:`method_order`.
    """
    from_schema = results.assign(**{c: np.nan for c in QUALITY_COLUMNS if c not in results.columns})
    t = from_schema[unscored_rows(from_schema)].copy()
    rank = {m: i for i, m in enumerate(method_order(t))}
    t["_rank"] = t["method"].map(rank)
    t = t.sort_values(["scene", "viewpoint", "_rank"], kind="stable")
    t["calibration_flagged"] = pd.to_numeric(t["calibration_score"], errors="coerce") > CALIBRATION_THRESHOLD
    return t[["scene", "viewpoint", "method", *QUALITY_COLUMNS, "calibration_flagged", "seconds"]].reset_index(
        drop=True)


def quality_summary(results: pd.DataFrame) -> pd.DataFrame:
    """:func:`quality_table` per method: ``method, frames``, the mean over its frames of every quality column and
    of ``seconds`` (NaN when any frame's is), and ``flagged``, how many frames the calibration check flags; in
    :func:`method_order`."""
    t = quality_table(results)
    rows = []
    for label in method_order(results):
        part = t[t["method"] == label]
        if len(part):
            rows.append({"method": label, "frames": len(part),
                         **{c: float(pd.to_numeric(part[c]).mean(skipna=False)) for c in (*QUALITY_COLUMNS,
                                                                                          "seconds")},
                         "flagged": int(part["calibration_flagged"].sum())})
    return pd.DataFrame(rows, columns=["method", "frames", *QUALITY_COLUMNS, "seconds", "flagged"])


def quality_markdown(table: pd.DataFrame) -> str:
    """Markdown document of :func:`quality_table`."""
    lines = [f"# Quality without ground truth ({NOTHING_SCORED})", "",
             "Per frame and method: medians over the validly predicted pixels of the ground-truth-free quality maps",
             "(reconstruction.quality; docs/real-captures.md) and the calibration check's score (flagged above "
             f"{CALIBRATION_THRESHOLD:g}).", "",
             "| scene | viewpoint | method | " + " | ".join(_md_cell(QUALITY_HEADERS[c]) for c in QUALITY_COLUMNS)
             + " | calibration flagged | seconds |",
             "|---|---|---|" + "---:|" * (len(QUALITY_COLUMNS) + 2)]
    for _, r in table.iterrows():
        cells = [r["scene"], r["viewpoint"], r["method"],
                 *(f"{float(r[c]):.4g}" if np.isfinite(float(r[c])) else "—" for c in QUALITY_COLUMNS),
                 "yes" if r["calibration_flagged"] else "no",
                 f"{float(r['seconds']):.2f}" if np.isfinite(float(r["seconds"])) else "—"]
        lines.append("| " + " | ".join(_md_cell(str(x)) for x in cells) + " |")
    return "\n".join(lines) + "\n"
