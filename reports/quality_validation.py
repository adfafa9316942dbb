"""The quality-validation statistics and tables (``python -m tools.research.validate_quality``), pure: per-pixel
measures and true error in, rank correlations, AUSE, per-family summaries, the calibration check's counts and the
``validation.md`` text out.

The script reads the frames and maps, runs the methods and writes the files; everything it computes from them is
here: :func:`frame_validation` (one frame: the rho and AUSE of every measure of :data:`MEASURES` and of the method's
confidence, and the rho of every product of uncertainty factors), :func:`ranking_summary` and
:func:`calibration_summary` (``validation.json``'s ``ranking`` and ``calibration``), :func:`validation_markdown`.
"""

from __future__ import annotations

import itertools
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from reconstruction.quality import (
    CALIBRATION_THRESHOLD,
    FACTORS,
    UNCERTAINTY_FACTORS,
    assess,
    combine,
    uncertainty_factors,
)
from reports.metrics import ause, pooled_sparsification_curves, scored_pixels, sparsification_curves, summary

__all__ = ["MEASURES", "CONFIDENCE", "RHO_BAR", "rank_correlation", "factor_subsets", "subset_key", "choose_subset",
           "choose_threshold", "FrameValidation", "frame_validation", "ranking_summary", "calibration_summary",
           "number_text", "validation_markdown"]

MEASURES = ("uncertainty", "photometric_residual", "distance_residual_m", "pair_agreement", "residual_uncertainty",
            "geometric_m", "disagreement")
"""The per-pixel maps of :func:`reconstruction.quality.assess` that are validated (higher = less trustworthy);
``uncertainty`` is the one to rank pixels by (``disagreement`` only for methods that give a reference distance)."""
CONFIDENCE = "confidence"
RHO_BAR = 0.5
"""Issue 19's bar for the rank correlation of the default method."""

def rank_correlation(measure: np.ndarray, error: np.ndarray) -> float:
    """Spearman rank correlation of ``measure`` (N,) with ``error`` (N,); a measure that is not a number counts as
    the largest (ties at the top).  NaN for fewer than 3 pixels or a constant input (unitless, -1..1)."""
    m = np.asarray(measure)
    m = np.where(np.isnan(m), np.inf, m)  # keeps float32 (ranks only): the pooled pixels of a split are many
    e = np.asarray(error)
    if m.size < 3:
        return float("nan")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a constant input: NaN, said by the result itself
        rho = stats.spearmanr(m, e).statistic
    return float(rho)


def factor_subsets(names: Sequence[str] = FACTORS) -> list[tuple[str, ...]]:
    """Every non-empty subset of the uncertainty factors ``names``, in order of size, then of ``names``."""
    return [tuple(c) for k in range(1, len(names) + 1) for c in itertools.combinations(names, k)]


def subset_key(names: Sequence[str]) -> str:
    """The column of a factor subset: ``factors:a*b``."""
    return "factors:" + "*".join(names)


def choose_subset(means: dict[str, float]) -> str | None:
    """The factor subset (a :func:`subset_key`) with the highest mean rho over frames; a tie goes to the smaller
    subset (listed first).  None when no mean is finite."""
    best = None
    for key, value in means.items():
        if np.isfinite(value) and (best is None or value > means[best]):
            best = key
    return best


def choose_threshold(exact: Sequence[float], perturbed: Sequence[float]) -> dict:
    """The calibration threshold that separates most frames (exact score <= t < perturbed score), the middle of
    the widest interval of such thresholds between two consecutive scores; and the count it separates.

    Args:
        exact, perturbed: the calibration scores of the exact and the perturbed frames (NaN = never separated).
    Returns:
        ``{"threshold": t, "separated": n, "frames": N}`` (t NaN without finite scores).
    """
    e = np.asarray(exact, np.float64)
    p = np.asarray(perturbed, np.float64)
    scores = np.unique(np.concatenate([e[np.isfinite(e)], p[np.isfinite(p)]]))
    if scores.size < 2:
        return {"threshold": float(scores[0]) if scores.size else float("nan"),
                "separated": int(np.sum((e <= scores[0]) & (p > scores[0]))) if scores.size else 0,
                "frames": int(e.size)}
    mids = (scores[:-1] + scores[1:]) / 2
    widths = np.diff(scores)
    counts = np.array([int(np.sum((e <= t) & (p > t))) for t in mids])
    best = np.flatnonzero(counts == counts.max())
    i = int(best[np.argmax(widths[best])])
    return {"threshold": float(mids[i]), "separated": int(counts[i]), "frames": int(e.size)}


@dataclass
class FrameValidation:
    """The ranking check of one frame.

    Attributes:
        row: the ``validation.csv`` row (module doc; rho unitless, AUSE and MAE metres).
        error: (N,) float32 true absolute error of the N validly predicted pixels with ground truth, metres.
        uncertainty: (N,) float32 ``uncertainty`` of those pixels (NaN = not a number).
        curves: per compared measure, ``(fractions, curve, oracle, N)`` of its sparsification (for pooling).
    """

    row: dict
    error: np.ndarray
    uncertainty: np.ndarray
    curves: dict[str, tuple] = field(default_factory=dict)


def frame_validation(frame, distance: np.ndarray, confidence: np.ndarray | None,
                     reference: np.ndarray | None = None) -> FrameValidation:
    """Rank correlation and AUSE of every measure (and of the method's confidence, negated) on one frame, and the
    rank correlation of every product of uncertainty factors (:func:`factor_subsets`; ``rho:factors:...``, NaN
    for a subset with a factor the prediction lacks).

    Args:
        frame: a frame with ground truth (``distance["C"]``, metres).
        distance: (H, W) C's predicted distance, metres (NaN, inf, <= 0 = no prediction).
        confidence: (H, W) the method's confidence (higher = more trustworthy) or None.
        reference: (H, W) the method's reference distance (:class:`reconstruction.methods.base.MethodOutput`),
            metres, or None.
    """
    gt = np.asarray(frame.distance["C"], np.float64)
    d = np.asarray(distance, np.float64)
    valid = np.isfinite(d) & (d > 0)
    scored = scored_pixels(gt)
    sel = scored & valid
    err = np.abs(d - gt)[sel]
    maps, quality = assess(frame, distance, confidence, reference)
    ranked = {m: maps[m] for m in MEASURES if m in maps}
    if confidence is not None:
        ranked[CONFIDENCE] = -np.asarray(confidence, np.float64)
    row = {"scene": frame.scene, "viewpoint": frame.viewpoint, "width": frame.width, "height": frame.height,
           "scored_px": int(scored.sum()), "valid_px": int(sel.sum()),
           "mae_m": summary(d, gt)["mae_m"], "mae_valid_m": float(err.mean()) if err.size else float("nan")}
    curves = {}
    for name in (*MEASURES, CONFIDENCE):
        if name not in ranked:
            row[f"rho:{name}"], row[f"ause_m:{name}"] = float("nan"), float("nan")
            continue
        u = np.asarray(ranked[name], np.float64)
        row[f"rho:{name}"] = rank_correlation(u[sel], err)
        fractions, curve, oracle = sparsification_curves(d, gt, -u, mask=valid)
        row[f"ause_m:{name}"] = ause(fractions, curve, oracle) if sel.any() else float("nan")
        curves[name] = (fractions, curve, oracle, int(sel.sum()))
    factors = uncertainty_factors(maps, confidence)
    for names in factor_subsets():
        ok = all(n in factors for n in names)
        row[f"rho:{subset_key(names)}"] = (rank_correlation(np.asarray(combine(factors, names), np.float64)[sel], err)
                                           if ok else float("nan"))
    row["uncertainty_median"] = quality["uncertainty_median"]
    row["calibration_score"] = quality["calibration_score"]
    row["calibration_flagged"] = quality["calibration_flagged"]
    return FrameValidation(row, err.astype(np.float32), maps["uncertainty"][sel].astype(np.float32), curves)


def _stats(values: Sequence[float]) -> dict:
    """Mean, median, min, max of the finite ``values`` and the share of all of them at least :data:`RHO_BAR`."""
    v = np.asarray(values, np.float64)
    f = v[np.isfinite(v)]
    nan = float("nan")
    return {"frames": int(v.size), "finite": int(f.size), "mean": float(f.mean()) if f.size else nan,
            "median": float(np.median(f)) if f.size else nan, "min": float(f.min()) if f.size else nan,
            "max": float(f.max()) if f.size else nan,
            "share_at_least_bar": float(np.mean(np.isfinite(v) & (v >= RHO_BAR))) if v.size else nan}


def _pooled(items: Sequence[FrameValidation]) -> dict:
    """Over the pixels of ``items`` pooled: the rho of ``uncertainty`` and every measure's AUSE (metres;
    :func:`reports.metrics.pooled_sparsification_curves`, pixel-weighted; NaN for the confidence unless every frame
    has one)."""
    out = {"pixels": int(sum(i.error.size for i in items))}
    out["rho:uncertainty"] = rank_correlation(np.concatenate([i.uncertainty for i in items]),
                                              np.concatenate([i.error for i in items]))
    for name in (*MEASURES, CONFIDENCE):
        # frames without a ranked pixel add nothing; the confidence only when every frame has one
        parts = [i.curves[name] for i in items if name in i.curves and i.curves[name][3] > 0]
        ok = bool(parts) and all(name in i.curves for i in items)
        out[f"ause_m:{name}"] = pooled_sparsification_curves(parts)["ause"] if ok else float("nan")
    return out


def ranking_summary(items: Sequence[FrameValidation], families: Sequence[str]) -> dict:
    """Per-frame statistics of every measure's rho, and per family and over all frames those of ``uncertainty``
    plus the pooled figures (:func:`_pooled`)."""
    rows = [i.row for i in items]
    per_measure = {name: _stats([r[f"rho:{name}"] for r in rows]) for name in (*MEASURES, CONFIDENCE)}
    subsets = {subset_key(n): _stats([r[f"rho:{subset_key(n)}"] for r in rows]) for n in factor_subsets()}
    fams = {}
    for fam in sorted(set(families)):
        mine = [i for i, f in zip(items, families, strict=True) if f == fam]
        fams[fam] = {**_stats([i.row["rho:uncertainty"] for i in mine]), "pooled": _pooled(mine)}
    chosen = choose_subset({k: v["mean"] if v["finite"] == v["frames"] else float("nan")
                            for k, v in subsets.items()})
    return {"measure": "uncertainty", "rho_bar": RHO_BAR, "per_frame": per_measure, "families": fams,
            "all": {**per_measure["uncertainty"], "pooled": _pooled(items)},
            "factor_subsets": subsets, "uncertainty_factors": list(UNCERTAINTY_FACTORS),
            "best_factor_subset": chosen}


def calibration_summary(rows: Sequence[dict], rotation: float, seed: int, asked: int) -> dict:
    """Counts of the calibration check over its ``rows`` (``calibration.csv``)."""
    exact = np.array([r["exact_score"] for r in rows], np.float64)
    pert = np.array([r["perturbed_score"] for r in rows], np.float64)
    nan = float("nan")
    return {"rotation_deg": rotation, "seed": seed, "threshold": CALIBRATION_THRESHOLD, "frames_asked": asked,
            "best_threshold": choose_threshold(exact, pert),
            "frames": len(rows), "separated": int(sum(r["separated"] for r in rows)),
            "exact_flagged": int(sum(r["exact_flagged"] for r in rows)),
            "perturbed_flagged": int(sum(r["perturbed_flagged"] for r in rows)),
            "max_exact_score": float(np.nanmax(exact)) if np.isfinite(exact).any() else nan,
            "min_perturbed_score": float(np.nanmin(pert)) if np.isfinite(pert).any() else nan,
            "every_perturbed_above_every_exact": bool(len(rows) and np.isfinite(exact).all()
                                                      and np.isfinite(pert).all() and pert.min() > exact.max())}


def number_text(x, fmt: str = ".3f") -> str:
    """``x`` formatted with ``fmt``, ``-`` for None, NaN and infinities."""
    return format(float(x), fmt) if x is not None and np.isfinite(float(x)) else "-"


def validation_markdown(result: dict, rows: Sequence[dict], calib_rows: Sequence[dict]) -> str:
    """``validation.md``: the per-frame, per-family and calibration tables and the verdict against issue 19's bars."""
    ranking, calib, method = result["ranking"], result["calibration"], result["method"]["label"]
    src = result["distances"]
    where = ("run by this job" if src["source"] == "run" else
             f"read from the results set {src['path']} (method {src['label']!r}, the configuration of {method!r})")
    sw = result["software"]
    lines = [f"# Quality without ground truth against true error: `{method}`", "",
             f"{result['frames']} frames with ground truth under {result['data_root']} "
             f"({len(ranking['families'])} families); tri360 {sw.get('tri360_version')} "
             f"(commit {sw.get('commit') or 'unknown'}); distances {where}.", "",
             "rho: Spearman rank correlation between the measure and the true absolute error over the validly "
             "predicted pixels (1 = ranks pixels exactly by error); AUSE: area between the MAE sparsification curve "
             "(pixels removed most uncertain first) and the oracle's, metres; the method's confidence is negated "
             "(least confident first).", "",
             "## Per frame", "",
             "| family | frame | MAE m | `uncertainty` rho / AUSE m | `photometric_residual` rho / AUSE | "
             "`distance_residual_m` rho / AUSE | method confidence rho / AUSE |",
             "|---|---|---:|---:|---:|---:|---:|"]
    for r in rows:
        cells = [f"{number_text(r[f'rho:{n}'])} / {number_text(r[f'ause_m:{n}'])}"
                 for n in ("uncertainty", "photometric_residual", "distance_residual_m", CONFIDENCE)]
        lines.append(f"| {r['family']} | {r['scene']}/{r['viewpoint']} | {number_text(r['mae_m'])} | "
                     + " | ".join(cells) + " |")
    lines += ["", "## Per family (`uncertainty`)", "",
              "| family | frames | mean rho | median rho | min rho | frames with rho >= 0.5 | pooled rho | "
              "pooled AUSE m |", "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for name, s in [*ranking["families"].items(), ("**all**", ranking["all"])]:
        share = round(s["share_at_least_bar"] * s["frames"]) if np.isfinite(s["share_at_least_bar"]) else 0
        lines.append(f"| {name} | {s['frames']} | {number_text(s['mean'])} | {number_text(s['median'])} | "
                     f"{number_text(s['min'])} | "
                     f"{share} of {s['frames']} | {number_text(s['pooled']['rho:uncertainty'])} | "
                     f"{number_text(s['pooled']['ause_m:uncertainty'])} |")
    per = ranking["per_frame"]
    lines += ["", "Mean rho over frames of the other measures: "
              + ", ".join(f"`{n}` {number_text(per[n]['mean'])}" for n in (*MEASURES[1:], CONFIDENCE)
                          if per[n]["finite"]) + "."]
    subsets, used = ranking["factor_subsets"], "*".join(ranking["uncertainty_factors"])
    lines += ["", "## Which factors make `uncertainty` (every product; mean rho over frames)", "",
              f"`uncertainty` is the product of `{used}` (reconstruction.quality.UNCERTAINTY_FACTORS; a factor the "
              "prediction lacks counts as 1). Highest mean rho here: "
              f"`{(ranking['best_factor_subset'] or '-').removeprefix('factors:')}`.", "",
              "| factors | mean rho | median rho | min rho |", "|---|---:|---:|---:|"]
    for key, st in sorted(subsets.items(), key=lambda kv: -kv[1]["mean"] if np.isfinite(kv[1]["mean"]) else 0):
        if st["finite"]:
            name = key.removeprefix("factors:")
            mark = "**" if key == ranking["best_factor_subset"] else ""
            lines.append(f"| {mark}`{name}`{mark} | {number_text(st['mean'])} | {number_text(st['median'])} | "
                         f"{number_text(st['min'])} |")
    lines += ["", f"## Calibration check (rotation {calib['rotation_deg']:g} deg of U and R, seed {calib['seed']}, "
              f"threshold {calib['threshold']:g})", ""]
    if calib_rows:
        lines += ["| family | frame | exact score | flagged | perturbed score | flagged | separated |",
                  "|---|---|---:|---|---:|---|---|"]
        for r in calib_rows:
            lines.append(f"| {r['family']} | {r['scene']}/{r['viewpoint']} | {number_text(r['exact_score'])} | "
                         f"{'yes' if r['exact_flagged'] else 'no'} | {number_text(r['perturbed_score'])} | "
                         f"{'yes' if r['perturbed_flagged'] else 'no'} | {'yes' if r['separated'] else 'no'} |")
        lines += ["", f"Separated (exact not flagged, perturbed flagged): {calib['separated']} of {calib['frames']} "
                  f"frames; every perturbed score above every exact one: "
                  f"{'yes' if calib['every_perturbed_above_every_exact'] else 'no'} (highest exact "
                  f"{number_text(calib['max_exact_score'])}, lowest perturbed "
                  f"{number_text(calib['min_perturbed_score'])}).",
                  "", f"The threshold that separates most of these frames (the middle of the widest such interval): "
                  f"{number_text(calib['best_threshold']['threshold'], '.4f')}, separating "
                  f"{calib['best_threshold']['separated']} of {calib['best_threshold']['frames']} "
                  "(reconstruction.quality.CALIBRATION_THRESHOLD is chosen so on the suite's dev split)."]
    else:
        lines.append("Not run (`--calibration-frames 0`).")
    a = ranking["all"]
    lines += ["", "## Against issue 19's bars", "",
              f"- `uncertainty` rho: mean over frames {number_text(a['mean'])}, median {number_text(a['median'])}, min "
              f"{number_text(a['min'])}; {round(a['share_at_least_bar'] * a['frames'])} of {a['frames']} frames at "
              f"least {RHO_BAR} (mean at least {RHO_BAR}: {'yes' if a['mean'] >= RHO_BAR else 'no'}; every frame: "
              f"{'yes' if a['min'] >= RHO_BAR else 'no'}; pooled rho {number_text(a['pooled']['rho:uncertainty'])})."]
    if calib_rows:
        bar = "yes" if calib["separated"] >= 0.9 * calib["frames"] else "no"
        note = "" if calib["frames"] == 10 else f"; {calib['frames']} frames checked, not 10"
        lines.append(f"- calibration check: {calib['separated']} of {calib['frames']} frames separated (at least 9 "
                     f"in 10: {bar}{note}).")
    return "\n".join(lines) + "\n"
