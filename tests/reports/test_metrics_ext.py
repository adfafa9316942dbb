"""reports.metrics, the extended metrics: percentiles, bad-pixel rates, tight deltas, coverage, depth boundaries,
the seam, AUSE and pooling, each checked against hand-computed values or an independent plain-Python computation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from reconstruction.camera.image_ops import dilate_wrapped
from reports.metrics import (
    AUSE_STEPS,
    SUMMARY_KEYS,
    ScoredMaps,
    depth_edges,
    pooled_summary,
    sparsification_curves,
    summary,
)

TOL = 1e-12  # metres or unitless shares: exact float64 arithmetic up to rounding
REL = 1e-9  # relative agreement demanded of percentiles and AUSE against the independent computation


# ------------------------------------------------------------------------------- independent reference code


def reference_errors(pred, gt, conf=None):
    """Plain-Python scoring of every pixel: (errors, confidences) of the scored pixels, row-major."""
    errs, confs = [], []
    for idx in np.ndindex(gt.shape):
        g, p = float(gt[idx]), float(pred[idx])
        if not (math.isfinite(g) and g > 0):
            continue
        errs.append(abs(p - g) if (math.isfinite(p) and p > 0) else g)
        confs.append(None if conf is None else float(conf[idx]))
    return errs, confs


def reference_percentile(values, q):
    """Linear interpolation between the closest ranks (numpy's default 'linear' method, written out)."""
    s = sorted(values)
    rank = q / 100.0 * (len(s) - 1)
    lo = math.floor(rank)
    hi = min(lo + 1, len(s) - 1)
    return s[lo] + (rank - lo) * (s[hi] - s[lo])


def reference_curves(errs, confs, steps):
    """Sparsification by explicit loops: keep the most confident pixels / the smallest errors.

    Pixels of equal confidence are removed in random order; the curve holds the expectation: the kept part of a
    run of ties contributes the run's mean error per kept pixel.
    """
    n = len(errs)
    levels = sorted(set(confs), reverse=True)
    runs = [[e for e, c in zip(errs, confs, strict=True) if c == level] for level in levels]
    by_err = sorted(errs)
    fr, curve, oracle = [], [], []
    for k in range(steps + 1):
        f = k / steps
        keep = max(n - math.floor(f * n), 1)
        total, left = 0.0, keep
        for run in runs:  # most confident run first
            take = min(left, len(run))
            total += math.fsum(run) if take == len(run) else take * math.fsum(run) / len(run)
            left -= take
            if left == 0:
                break
        fr.append(f)
        curve.append(total / keep)
        oracle.append(math.fsum(by_err[:keep]) / keep)
    return fr, curve, oracle


def reference_ause(errs, confs, steps):
    fr, curve, oracle = reference_curves(errs, confs, steps)
    d = [c - o for c, o in zip(curve, oracle, strict=True)]
    return math.fsum((fr[i + 1] - fr[i]) * (d[i + 1] + d[i]) / 2 for i in range(steps))


def random_case(seed, h=40, w=80):
    """Ground truth 1-6 m with some sky, a noisy prediction with invalid values, distinct confidences."""
    rng = np.random.default_rng(seed)
    surface = rng.uniform(1.0, 6.0, (h, w))
    pred = surface * (1 + rng.normal(0, 0.05, (h, w))) + rng.normal(0, 0.02, (h, w))
    conf = -np.abs(pred - surface) + rng.normal(0, 0.05, (h, w))  # informative but imperfect
    gt = np.where(rng.random((h, w)) < 0.05, np.inf, surface)
    bad = rng.random((h, w))
    pred[bad < 0.03] = np.nan
    pred[(bad >= 0.03) & (bad < 0.05)] = -1.0
    pred[(bad >= 0.05) & (bad < 0.06)] = np.inf
    conf[bad < 0.01] = np.nan  # a run of ties: NaN = least confident
    return pred, gt, conf


# ----------------------------------------------------------------------------------- keys and pixel metrics


def test_keys_and_order():
    pred, gt, conf = random_case(0)
    s = summary(pred, gt)
    assert list(s) == list(SUMMARY_KEYS) and "ause" not in s
    s = summary(pred, gt, conf)
    assert list(s) == [*SUMMARY_KEYS, "ause"]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_percentiles_match_an_independent_computation(seed):
    pred, gt, _ = random_case(seed)
    errs, _ = reference_errors(pred, gt)
    s = summary(pred.astype(np.float32), gt.astype(np.float32)) if seed == 2 else summary(pred, gt)
    if seed == 2:  # float32 inputs are scored in float64 after conversion
        errs, _ = reference_errors(pred.astype(np.float32), gt.astype(np.float32))
    assert s["valid_px"] == len(errs)
    for q in (50, 90, 95, 99):
        assert s[f"p{q}_m"] == pytest.approx(reference_percentile(errs, q), rel=REL)
    assert s["mae_m"] == pytest.approx(math.fsum(errs) / len(errs), rel=REL)
    assert s["p50_m"] == pytest.approx(s["median_m"], rel=1e-15)


def test_percentiles_hand_computed():
    gt = np.full((1, 5), 10.0)
    pred = np.array([[10.0, 11.0, 12.0, 13.0, np.nan]])  # errors 0, 1, 2, 3 and 10 (invalid: error = gt)
    s = summary(pred, gt)
    # linear: rank = q/100 * 4; p90 -> rank 3.6 -> 3 + 0.6 * (10 - 3) = 7.2; p99 -> 3.96 -> 3 + 0.96 * 7 = 9.72
    assert s["p50_m"] == pytest.approx(2.0, abs=TOL)
    assert s["p90_m"] == pytest.approx(7.2, abs=TOL)
    assert s["p95_m"] == pytest.approx(3 + 0.8 * 7, abs=TOL)
    assert s["p99_m"] == pytest.approx(9.72, abs=TOL)


def test_bad_pixel_rates_tight_deltas_and_coverage_hand_computed():
    gt = np.array([[10.0, 10.0, 10.0, 10.0, 10.0, 10.0, 10.0, 10.0, np.inf]])
    # errors 0.05, 0.15, 0.3, 0.7, 0.9, 1.5 m (0.5 %, 1.5 %, 3 %, 7 %, 9 %, 15 % of 10 m), then NaN and 0
    pred = np.array([[10.05, 9.85, 10.3, 10.7, 9.1, 11.5, np.nan, 0.0, 5.0]])
    s = summary(pred, gt)
    n = 8
    assert s["valid_px"] == n
    assert s["bad_1pct"] == pytest.approx(7 / n, abs=TOL)  # all but 0.5 % (invalid ones are always bad)
    assert s["bad_2pct"] == pytest.approx(6 / n, abs=TOL)
    assert s["bad_5pct"] == pytest.approx(5 / n, abs=TOL)
    assert s["outlier_rate"] == pytest.approx(3 / n, abs=TOL)  # 15 % and the two invalid
    # ratios max(p/g, g/p): 1.005, 1.0152, 1.03, 1.07, 1.0989, 1.15; invalid ones fail every delta
    assert s["delta105"] == pytest.approx(3 / n, abs=TOL)
    assert s["delta110"] == pytest.approx(5 / n, abs=TOL)
    assert s["delta1"] == pytest.approx(6 / n, abs=TOL)
    assert s["coverage"] == pytest.approx(6 / n, abs=TOL)  # the sky pixel's prediction does not count


def test_delta_thresholds_are_strict():
    gt = np.array([[2.0, 4.0]])
    s = summary(np.array([[2.0 * 1.25, 4.0]]), gt)  # exact ratio 1.25 fails delta1 (strict <)
    assert s["delta1"] == 0.5 and s["delta110"] == 0.5 and s["delta105"] == 0.5
    s = summary(np.array([[2.0 / 1.0625, 4.0]]), gt)  # ratio 1.0625 (exact): passes 1.10, fails 1.05
    assert s["delta110"] == 1.0 and s["delta105"] == 0.5


# ------------------------------------------------------------------------------------------------ boundaries


def test_depth_edges_hand_computed():
    # one row: horizontal pairs only
    d = np.array([[1.0, 1.05, 1.5, np.inf, np.inf, np.nan, 2.0, 2.0]])
    # pairs: 1|1.05 no (ln 1.05 < ln 1.1), 1.05|1.5 yes, 1.5|inf yes, inf|inf no, inf|NaN no, NaN|2 no, 2|2 no,
    # and 2|1 across the seam yes (columns wrap); both pixels of a jumping pair are edge pixels
    np.testing.assert_array_equal(depth_edges(d)[0], [True, True, True, True, False, False, False, True])
    # one column: vertical pairs only, rows do not wrap (top 1 m, bottom 5 m: no edge between them)
    col = np.array([[1.0], [1.0], [1.2], [np.nan], [5.0]])
    np.testing.assert_array_equal(depth_edges(col)[:, 0], [False, True, True, False, False])
    # two rows: the union of both
    d2 = np.vstack([d, np.ones((1, 8))])
    # vertical pairs jump at columns 2 (1.5|1), 3 and 4 (inf|1), 6 and 7 (2|1); not 5 (NaN) nor 0, 1
    np.testing.assert_array_equal(depth_edges(d2)[0], [True, True, True, True, True, False, True, True])
    np.testing.assert_array_equal(depth_edges(d2)[1], [False, False, True, True, True, False, True, True])
    assert not depth_edges(np.array([[-1.0, 3.0, 0.0]])).any()  # non-positive values never jump


def test_dilate_wraps_columns_not_rows():
    m = np.zeros((5, 8), dtype=bool)
    m[0, 0] = True
    d = dilate_wrapped(m, 1)
    expected = np.zeros((5, 8), dtype=bool)
    expected[0:2, [7, 0, 1]] = True
    np.testing.assert_array_equal(d, expected)
    np.testing.assert_array_equal(dilate_wrapped(m, 0), m)
    assert dilate_wrapped(m, 3)[:4].all(axis=0)[[5, 6, 7, 0, 1, 2, 3]].all()
    assert not dilate_wrapped(m, 3)[4].any()


def _step(h, w, cut):
    """2 m left of column ``cut``, 4 m from it on: depth edges at columns cut-1, cut and (seam) W-1, 0."""
    d = np.full((h, w), 4.0)
    d[:, :cut] = 2.0
    return d


@pytest.mark.parametrize("shift, precision, recall", [(0, 1.0, 1.0), (1, 1.0, 1.0), (3, 0.5, 0.5)])
def test_boundary_precision_recall_with_shifted_edges(shift, precision, recall):
    h, w = 6, 24
    gt = _step(h, w, 12)
    s = summary(_step(h, w, 12 + shift), gt)
    # GT edge columns {11, 12, 23, 0}; the prediction's {11 + shift, 12 + shift, 23, 0}: a shift of 1 column is
    # within the 1-pixel tolerance; a shift of 3 leaves only the seam edge matched (half of each set)
    assert s["boundary_precision"] == pytest.approx(precision, abs=TOL)
    assert s["boundary_recall"] == pytest.approx(recall, abs=TOL)


def test_boundary_of_a_smooth_or_invalid_prediction():
    h, w = 6, 24
    gt = _step(h, w, 12)
    # a ramp 2 -> 4 -> 2 m with steps below 10 %: no predicted edge at all
    ramp = np.tile(np.concatenate([np.linspace(2.0, 4.0, 12), np.linspace(4.0, 2.0, 12)]), (h, 1))
    s = summary(ramp, gt)
    assert s["boundary_recall"] == 0.0 and math.isnan(s["boundary_precision"])
    # invalid predictions on both sides of the middle edge: no edge can be predicted there
    pred = gt.copy()
    pred[:, 11:13] = np.nan
    s = summary(pred, gt)
    assert s["boundary_precision"] == 1.0  # the seam edge (columns 23, 0), correct
    assert s["boundary_recall"] == pytest.approx(0.5, abs=TOL)  # columns 11, 12 missed
    # a spurious edge (a 3 m patch at columns 4-5, rows 2-3) lowers precision: it adds 12 edge pixels
    pred = gt.copy()
    pred[2:4, 4:6] = 3.0
    s = summary(pred, gt)
    assert s["boundary_recall"] == 1.0
    assert s["boundary_precision"] == pytest.approx(4 * h / (4 * h + 12), abs=TOL)


def test_boundary_counts_inside_a_mask():
    h, w = 6, 24
    gt = _step(h, w, 12)
    pred = _step(h, w, 15)
    mask = np.zeros((h, w), dtype=bool)
    mask[:, 8:20] = True  # holds only the middle edges: none matched
    s = summary(pred, gt, mask=mask)
    assert s["boundary_precision"] == 0.0 and s["boundary_recall"] == 0.0
    mask[:] = False
    mask[:, [23, 0]] = True  # only the seam edges: all matched
    s = summary(pred, gt, mask=mask)
    assert s["boundary_precision"] == 1.0 and s["boundary_recall"] == 1.0


# ------------------------------------------------------------------------------------------------------ seam


def test_seam_hand_computed():
    h, w = 5, 8
    gt = np.full((h, w), 2.5)
    gt[:, 0], gt[:, -1] = 2.0, 3.0  # a genuine 1 m difference across the seam: not the method's fault
    gt[4, -1] = np.inf  # row 4: the right seam pixel is not scored
    pred = gt.copy()
    pred[0, 0] = 2.1  # row 0: |(2.1 - 3) - (2 - 3)| = 0.1
    pred[1, -1] = 2.8  # row 1: |(2 - 2.8) - (2 - 3)| = 0.2
    pred[2, 0] = np.nan  # row 2: invalid prediction, row skipped
    pred[3, 4] = 9.0  # row 3: exact at the seam (an error elsewhere does not count): 0
    s = summary(pred, gt)
    assert s["seam_m"] == pytest.approx((0.1 + 0.2 + 0.0) / 3, abs=TOL)
    mask = np.ones((h, w), dtype=bool)
    mask[1, -1] = False  # a row counts only when both its seam pixels are inside the mask: rows 0 and 3 left
    assert summary(pred, gt, mask=mask)["seam_m"] == pytest.approx(0.05, abs=TOL)
    assert math.isnan(summary(np.full((h, w), np.nan), gt)["seam_m"])


# ------------------------------------------------------------------------------------------------------ AUSE


@pytest.mark.parametrize("seed, steps", [pytest.param(0, AUSE_STEPS, marks=pytest.mark.slow),
                                         pytest.param(1, AUSE_STEPS, marks=pytest.mark.slow), (2, 7), (3, 100)])
def test_ause_and_curves_match_an_independent_computation(seed, steps):
    pred, gt, conf = random_case(seed)
    errs, confs = reference_errors(pred, gt, conf)
    confs = [-math.inf if math.isnan(c) else c for c in confs]  # NaN confidence = least confident
    fr, curve, oracle = sparsification_curves(pred, gt, conf, steps=steps)
    ref_fr, ref_curve, ref_oracle = reference_curves(errs, confs, steps)
    np.testing.assert_allclose(fr, ref_fr, rtol=0, atol=1e-15)
    np.testing.assert_allclose(curve, ref_curve, rtol=REL, atol=0)
    np.testing.assert_allclose(oracle, ref_oracle, rtol=REL, atol=0)
    assert curve[0] == pytest.approx(summary(pred, gt)["mae_m"], rel=REL)
    if steps == AUSE_STEPS:
        ause = summary(pred, gt, conf)["ause"]
        assert ause == pytest.approx(reference_ause(errs, confs, steps), rel=REL)
        assert ause > 0.0


def test_ause_of_an_oracle_confidence_is_zero_and_of_an_inverse_one_is_large():
    pred, gt, _ = random_case(4)
    valid = np.isfinite(pred) & (pred > 0)
    err = np.where(valid, np.abs(np.where(valid, pred, 0.0) - gt), gt)
    assert summary(pred, gt, -err)["ause"] == 0.0  # same order as the oracle: identical curves
    fr, curve, oracle = sparsification_curves(pred, gt, err)  # most confident where worst
    anti = summary(pred, gt, err)["ause"]
    assert anti == pytest.approx(np.sum(0.5 * (curve[1:] + curve[:-1] - oracle[1:] - oracle[:-1]) * np.diff(fr)),
                                 rel=1e-12)
    assert anti > summary(pred, gt, np.zeros_like(gt))["ause"] > 0.0


def test_tied_confidences_are_removed_in_expectation():
    pred, gt, _ = random_case(5)
    mae = summary(pred, gt)["mae_m"]
    # a constant confidence says nothing: the curve stays at the MAE (random removal, in expectation)
    _, curve, oracle = sparsification_curves(pred, gt, np.full(gt.shape, 0.3))
    np.testing.assert_allclose(curve, mae, rtol=1e-12, atol=0)
    # two confidence levels: the confident half first, then a random part of the other half
    errs, _ = reference_errors(pred, gt)
    scored = np.isfinite(gt)
    conf = np.zeros(gt.shape)
    conf[:, : gt.shape[1] // 2] = 1.0
    hi = [e for e, c in zip(errs, conf[scored], strict=True) if c == 1.0]
    lo = [e for e, c in zip(errs, conf[scored], strict=True) if c == 0.0]
    fr, curve, _ = sparsification_curves(pred, gt, conf, steps=10)
    n = len(errs)
    for k in range(11):
        keep = max(n - math.floor(k * n / 10), 1)
        if keep >= len(hi):
            expected = (math.fsum(hi) + (keep - len(hi)) * math.fsum(lo) / len(lo)) / keep
        else:
            expected = math.fsum(hi) / len(hi)  # a random part of the confident half: its mean
        assert curve[k] == pytest.approx(expected, rel=1e-12), k


def test_ause_without_pixels_and_without_confidence():
    gt = np.full((2, 4), np.inf)
    s = summary(np.ones((2, 4)), gt, np.ones((2, 4)))
    assert s["valid_px"] == 0 and math.isnan(s["ause"]) and math.isnan(s["coverage"])
    fr, curve, oracle = sparsification_curves(np.ones((2, 4)), gt, np.ones((2, 4)))
    assert fr.shape == (AUSE_STEPS + 1,) and np.isnan(curve).all() and np.isnan(oracle).all()
    with pytest.raises(ValueError, match="confidence"):
        sparsification_curves(np.ones((2, 4)), gt, None)


# --------------------------------------------------------------------------------------------------- pooling


@pytest.mark.slow
def test_pooled_summary_is_over_the_union_of_pixels():
    a = random_case(6, 40, 80)
    b = random_case(7, 20, 40)
    pooled = pooled_summary([a, b])
    sa, sb = summary(*a), summary(*b)
    n = sa["valid_px"] + sb["valid_px"]
    assert pooled["valid_px"] == n
    assert pooled["mae_m"] == pytest.approx((sa["mae_m"] * sa["valid_px"] + sb["mae_m"] * sb["valid_px"]) / n,
                                            rel=1e-12)
    assert pooled["coverage"] == pytest.approx((sa["coverage"] * sa["valid_px"] + sb["coverage"] * sb["valid_px"])
                                               / n, rel=1e-12)
    ea, ca = reference_errors(*a)
    eb, cb = reference_errors(*b)
    for q in (50, 90, 95, 99):
        assert pooled[f"p{q}_m"] == pytest.approx(reference_percentile(ea + eb, q), rel=REL)
    confs = [-math.inf if math.isnan(c) else c for c in ca + cb]
    assert pooled["ause"] == pytest.approx(reference_ause(ea + eb, confs, AUSE_STEPS), rel=REL)
    # one frame pooled alone is that frame's summary; a frame pooled with itself keeps every mean and share
    assert pooled_summary([a]) == summary(*a)
    twice = pooled_summary([a, a])
    for key in ("mae_m", "rmse_m", "absrel", "delta1", "bad_2pct", "coverage", "boundary_precision",
                "boundary_recall", "seam_m", "outlier_rate"):
        assert twice[key] == pytest.approx(sa[key], rel=1e-12), key
    assert twice["valid_px"] == 2 * sa["valid_px"]


def test_pooled_summary_with_masks_and_without_confidence():
    pred, gt, conf = random_case(8)
    mask = np.zeros(gt.shape, dtype=bool)
    mask[:20] = True
    pooled = pooled_summary([(pred, gt, None, mask), (pred, gt, None, ~mask)])
    whole = summary(pred, gt)
    assert "ause" not in pooled
    for key in ("mae_m", "rmse_m", "median_m", "p90_m", "delta105", "bad_1pct", "coverage"):
        assert pooled[key] == pytest.approx(whole[key], rel=1e-12), key
    assert pooled["valid_px"] == whole["valid_px"]


def test_pooled_summary_rejects_bad_input():
    pred, gt, conf = random_case(9, 10, 20)
    with pytest.raises(ValueError, match="confidence map or none"):
        pooled_summary([(pred, gt, conf), (pred, gt)])
    with pytest.raises(ValueError, match="at least one"):
        pooled_summary([])
    with pytest.raises(ValueError, match="entries"):
        pooled_summary([(pred,)])
    with pytest.raises(ValueError, match=r"\(10, 20\) and \(10, 19\)"):
        pooled_summary([(pred, gt), (pred, gt[:, :-1])])


# ---------------------------------------------------------------------------------------- masks and shapes


def test_mask_selects_pixels_like_removing_their_ground_truth():
    pred, gt, conf = random_case(10)
    mask = np.zeros(gt.shape, dtype=bool)
    mask[5:30, 10:70] = True
    masked = summary(pred, gt, conf, mask=mask)
    cut = summary(pred, np.where(mask, gt, np.inf), conf)
    pixel_keys = [k for k in masked if k not in ("boundary_precision", "boundary_recall", "seam_m")]
    for key in pixel_keys:
        assert masked[key] == pytest.approx(cut[key], rel=1e-12, abs=1e-15), key
    scored = ScoredMaps(pred, gt, conf)
    for got, want in ((scored.summary(mask), masked), (scored.summary(), summary(pred, gt, conf))):
        assert list(got) == list(want)
        np.testing.assert_array_equal(list(got.values()), list(want.values()))  # NaN == NaN here


def test_shape_errors_name_both_shapes():
    with pytest.raises(ValueError, match=r"\(2, 4\) and \(2, 3\)"):
        summary(np.ones((2, 4)), np.ones((2, 3)))
    with pytest.raises(ValueError, match=r"confidence.*\(3, 4\) and \(2, 4\)"):
        summary(np.ones((2, 4)), np.ones((2, 4)), np.ones((3, 4)))
    with pytest.raises(ValueError, match=r"mask.*\(2, 5\) and \(2, 4\)"):
        summary(np.ones((2, 4)), np.ones((2, 4)), mask=np.ones((2, 5), dtype=bool))
    with pytest.raises(ValueError, match="bool"):
        summary(np.ones((2, 4)), np.ones((2, 4)), mask=np.ones((2, 4)))
    with pytest.raises(ValueError, match=r"\(4,\) and \(4,\)"):
        summary(np.ones(4), np.ones(4))
