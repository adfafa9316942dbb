"""reports.metrics: hand-computed summary values, invalid-prediction scoring and breakdown bins."""

from __future__ import annotations

import math

import numpy as np
import pytest

from harness.data.frame import Frame
from reconstruction.camera.rig import Rig
from reports.metrics import (
    ANGLE_EDGES_DEG,
    DISTANCE_EDGES_M,
    SUMMARY_KEYS,
    TEXTURE_EDGES,
    angle_to_baseline_deg,
    binned_errors,
    breakdown,
    summary,
    texture_magnitude,
)

TOL = 1e-12  # metres (or unitless shares): the metrics are exact arithmetic on float64


def make_frame(width=36, height=18, gt=None, image_c=None) -> Frame:
    """A tiny in-memory frame: default rig at the origin, grey images, constant 2 m ground truth."""
    grey = np.full((height, width, 3), 128, dtype=np.uint8)
    gt = np.full((height, width), 2.0, dtype=np.float32) if gt is None else gt.astype(np.float32)
    return Frame(scene="unit", viewpoint="v0", width=width, height=height, baseline_m=0.4,
                 cameras=Rig().poses(),
                 images={"C": grey if image_c is None else image_c, "U": grey, "R": grey},
                 distance={"C": gt, "U": gt, "R": gt})


# ----------------------------------------------------------------------------------------------- summary


def test_summary_hand_computed():
    gt = np.array([[1.0, 2.0], [4.0, np.inf]])
    pred = np.array([[1.05, 1.0], [np.nan, 3.0]])
    # scored pixels: gt 1, 2, 4 (inf = no surface); errors 0.05, 1.0 and 4.0
    # (the NaN prediction is scored with |err| = gt)
    s = summary(pred, gt)
    assert s["valid_px"] == 3
    assert s["mae_m"] == pytest.approx(5.05 / 3, abs=TOL)
    assert s["rmse_m"] == pytest.approx(math.sqrt((0.05**2 + 1.0 + 16.0) / 3), abs=TOL)
    assert s["median_m"] == pytest.approx(1.0, abs=TOL)
    assert s["absrel"] == pytest.approx((0.05 + 0.5 + 1.0) / 3, abs=TOL)
    assert s["delta1"] == pytest.approx(1 / 3, abs=TOL)  # only ratio 1.05 < 1.25; ratio 2 and the NaN fail
    assert s["outlier_rate"] == pytest.approx(2 / 3, abs=TOL)  # 1.0 > 0.2 and the NaN; 0.05 <= 0.1 is not
    # the original keys come first, in their original order, then the extended ones (reports.metrics.SUMMARY_KEYS)
    assert list(s)[:7] == ["mae_m", "rmse_m", "median_m", "absrel", "delta1", "outlier_rate", "valid_px"]
    assert list(s) == list(SUMMARY_KEYS)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf, 0.0, -1.5])
def test_invalid_prediction_counts_with_error_equal_to_gt(bad):
    gt = np.array([[3.0, 2.0]])
    pred = np.array([[bad, 2.0]])
    s = summary(pred, gt)
    assert s["valid_px"] == 2  # invalid predictions are scored, not dropped
    assert s["mae_m"] == pytest.approx(3.0 / 2, abs=TOL)
    assert s["median_m"] == pytest.approx(1.5, abs=TOL)
    assert s["absrel"] == pytest.approx(0.5, abs=TOL)
    assert s["delta1"] == pytest.approx(0.5, abs=TOL)
    assert s["outlier_rate"] == pytest.approx(0.5, abs=TOL)
    # every pixel metric is finite; the true 3 m | 2 m depth edge is missed (no predicted edge beside an invalid
    # prediction: recall 0, precision undefined), and the one seam row has an invalid pixel (no seam row)
    pixel_keys = [k for k in SUMMARY_KEYS if k not in ("boundary_precision", "boundary_recall", "seam_m")]
    assert all(math.isfinite(s[k]) for k in pixel_keys)
    assert s["boundary_recall"] == 0.0 and math.isnan(s["boundary_precision"]) and math.isnan(s["seam_m"])


def test_perfect_prediction_and_delta_boundary():
    gt = np.array([[2.0, 4.0, 8.0]])
    s = summary(gt.copy(), gt)
    assert s["mae_m"] == 0.0 and s["rmse_m"] == 0.0 and s["delta1"] == 1.0 and s["outlier_rate"] == 0.0
    # ratio exactly 1.25 is not "< 1.25"
    s = summary(np.array([[2.5, 4.0, 8.0]]), gt)
    assert s["delta1"] == pytest.approx(2 / 3, abs=TOL)


def test_no_ground_truth_gives_nan_and_zero_pixels():
    gt = np.full((2, 4), np.inf)
    s = summary(np.ones((2, 4)), gt)
    assert s["valid_px"] == 0
    assert math.isnan(s["mae_m"]) and math.isnan(s["delta1"])


def test_shape_mismatch_is_an_error():
    with pytest.raises(ValueError, match="same shape"):
        summary(np.ones((2, 4)), np.ones((2, 3)))


# ------------------------------------------------------------------------------------------ binned errors


def test_binned_errors_mean_median_count():
    values = np.array([0.5, 0.7, 1.5, 1.2, 1.9, 5.0, 3.0, -1.0])
    err = np.array([1.0, 3.0, 2.0, 4.0, 6.0, 7.0, 10.0, 9.0])
    mae, med, n = binned_errors(values, err, np.array([0.0, 1.0, 2.0, 3.0]))
    # bin [0,1): 1, 3; bin [1,2): 2, 4, 6; bin [2,3]: 10 (value == last edge joins the last bin);
    # 5.0 and -1.0 are outside and dropped
    np.testing.assert_array_equal(n, [2, 3, 1])
    np.testing.assert_allclose(mae, [2.0, 4.0, 10.0], atol=TOL)
    np.testing.assert_allclose(med, [2.0, 4.0, 10.0], atol=TOL)
    mae, med, n = binned_errors(np.array([0.5]), np.array([1.0]), np.array([0.0, 1.0, 2.0]))
    assert n.tolist() == [1, 0] and math.isnan(mae[1]) and math.isnan(med[1])


# ---------------------------------------------------------------------------------------------- breakdown


def _rows(rows, kind):
    return [r for r in rows if r["kind"] == kind]


def test_breakdown_angle_to_up_baseline_is_colatitude():
    # U is straight above C, so the angle to the C-U baseline is the colatitude 180 * (v + 0.5) / H degrees:
    # with H = 18 row v lies exactly in the 10-degree bin v.  Row v predicts gt + 0.01 * v metres.
    w, h = 36, 18
    frame = make_frame(w, h)
    pred = frame.distance["C"] + 0.01 * np.arange(h)[:, None]
    rows = _rows(breakdown(frame, pred), "angle_U")
    assert len(rows) == 18
    assert [r["bin_lo"] for r in rows] == list(ANGLE_EDGES_DEG[:-1])
    assert all(r["n_px"] == w for r in rows)
    np.testing.assert_allclose([r["mae_m"] for r in rows], 0.01 * np.arange(h), atol=1e-6)  # float32 gt
    np.testing.assert_allclose([r["median_m"] for r in rows], 0.01 * np.arange(h), atol=1e-6)


def test_breakdown_angle_to_right_baseline():
    # R is to the right (+X): the angle is arccos(cos(phi) * sin(lam)); the bins are symmetric about 90 deg,
    # and the pixels nearest the right-looking direction (u + 0.5 = 0.75 W, equator) fall into bin 0.
    # A few pixels of this grid lie on a bin edge up to rounding (|angle - edge| ~ 1e-14 deg; the next nearest is
    # 0.14 deg away): the last bits of numpy's SIMD trigonometry differ between CPUs, so such a pixel may fall
    # into either neighbouring bin.  Every other pixel has one right bin.
    w, h = 36, 18
    edge_tol_deg = 1e-6
    frame = make_frame(w, h)
    rows = _rows(breakdown(frame, frame.distance["C"]), "angle_R")
    counts = np.array([r["n_px"] for r in rows])
    assert counts.sum() == w * h
    v, u = np.mgrid[0:h, 0:w]
    lam = 2 * np.pi * (u + 0.5) / w - np.pi
    phi = np.pi / 2 - np.pi * (v + 0.5) / h
    ang = np.degrees(np.arccos(np.clip(np.cos(phi) * np.sin(lam), -1, 1))).ravel()
    on_edge = np.abs(ang[:, None] - ANGLE_EDGES_DEG[None, 1:-1]).min(axis=1) < edge_tol_deg
    assert 0 < on_edge.sum() <= 8  # the property below is tested with ambiguity, but not much of it
    n_bins = len(ANGLE_EDGES_DEG) - 1
    sure = np.histogram(ang[~on_edge], bins=ANGLE_EDGES_DEG)[0]
    # a pixel on edge k (1 <= k < n_bins) may land in bin k - 1 or bin k
    edge_index = np.abs(ang[on_edge, None] - ANGLE_EDGES_DEG[None, :]).argmin(axis=1)
    maybe = np.zeros(n_bins, int)
    np.add.at(maybe, edge_index - 1, 1)
    np.add.at(maybe, edge_index, 1)
    assert np.all(counts >= sure) and np.all(counts <= sure + maybe), (counts, sure, maybe)
    # mirror symmetry about 90 deg, up to the pixels on an edge
    assert np.abs(counts - counts[::-1]).sum() <= 2 * on_edge.sum(), counts
    assert np.array_equal(sure, sure[::-1])
    assert counts[0] > 0 and all(r["mae_m"] == 0.0 for r in rows if r["n_px"])


def test_angle_follows_a_moved_and_rotated_rig():
    # move and yaw the whole rig: the baselines turn with it, so each pixel's angle must not change
    frame = make_frame(36, 18)
    base_u, base_r = angle_to_baseline_deg(frame, "U"), angle_to_baseline_deg(frame, "R")
    frame.cameras = Rig(position=np.array([1.0, 2.0, 0.5]), yaw_rad=0.7).poses()
    np.testing.assert_allclose(angle_to_baseline_deg(frame, "U"), base_u, atol=1e-9)  # degrees
    np.testing.assert_allclose(angle_to_baseline_deg(frame, "R"), base_r, atol=1e-9)
    # right-looking pixels (u + 0.5 = 0.75 W) on the equator rows are ~5 degrees from the R baseline
    assert angle_to_baseline_deg(frame, "R")[8:10, 26].max() == pytest.approx(np.hypot(5, 5), abs=0.05)


def test_breakdown_distance_bins_and_sky():
    w, h = 8, 4
    # one column per distance: 0.5, 1.5, 2.5, 4, 6, 10 m, then two columns of sky (+inf, not scored)
    col = np.array([0.5, 1.5, 2.5, 4.0, 6.0, 10.0, np.inf, np.inf])
    gt = np.tile(col, (h, 1))
    pred = gt * 1.1  # error = 10 % of gt
    rows = _rows(breakdown(make_frame(w, h, gt=gt), pred), "distance")
    assert [(r["bin_lo"], r["bin_hi"]) for r in rows] == list(zip(DISTANCE_EDGES_M[:-1], DISTANCE_EDGES_M[1:],
                                                                  strict=True))
    assert [r["n_px"] for r in rows] == [h] * 6
    np.testing.assert_allclose([r["mae_m"] for r in rows], 0.1 * col[:6], rtol=1e-6)
    assert rows[-1]["bin_hi"] == math.inf


def test_breakdown_texture_bins_on_a_ramp():
    # a vertical ramp of 5 grey levels per row reads 5 (bin 4-8) inside and 2.5 (bin 2-4) on the top and
    # bottom rows (replicated border); columns wrap, so there is no edge at the seam
    w, h = 16, 8
    ramp = (40 + 5 * np.arange(h))[:, None].repeat(w, axis=1).astype(np.uint8)
    img = np.repeat(ramp[:, :, None], 3, axis=2)
    mag = texture_magnitude(img)
    np.testing.assert_allclose(mag[1:-1], 5.0, atol=1e-5)
    np.testing.assert_allclose(mag[[0, -1]], 2.5, atol=1e-5)
    rows = _rows(breakdown(make_frame(w, h, image_c=img), np.full((h, w), 2.0)), "texture")
    assert [r["bin_lo"] for r in rows] == list(TEXTURE_EDGES[:-1])
    counts = {r["bin_lo"]: r["n_px"] for r in rows}
    assert counts[2.0] == 2 * w and counts[4.0] == (h - 2) * w and sum(counts.values()) == w * h


def test_texture_flat_image_and_seam():
    img = np.zeros((4, 8, 3), dtype=np.uint8)
    img[:, 4:] = 80  # two vertical edges: at u = 3|4 and across the seam 7|0
    mag = texture_magnitude(img)
    assert np.all(mag[:, [1, 2, 5, 6]] == 0.0)
    np.testing.assert_allclose(mag[:, [0, 3, 4, 7]], 40.0, atol=1e-5)  # (80 - 0) / 2 grey levels per pixel


def test_breakdown_scores_invalid_predictions_like_summary():
    w, h = 8, 4
    frame = make_frame(w, h)
    pred = np.full((h, w), 2.0)
    pred[0, :] = np.nan  # error 2 m on the top row
    rows = breakdown(frame, pred)
    for kind in ("angle_U", "angle_R", "distance", "texture"):
        rs = _rows(rows, kind)
        n = sum(r["n_px"] for r in rs)
        total = sum(r["mae_m"] * r["n_px"] for r in rs if r["n_px"])
        assert n == w * h
        assert total / n == pytest.approx(summary(pred, frame.distance["C"])["mae_m"], abs=1e-9)


def test_breakdown_needs_ground_truth_and_matching_shape():
    frame = make_frame(8, 4)
    with pytest.raises(ValueError, match="shape"):
        breakdown(frame, np.ones((4, 9)))
    frame.distance = {}
    with pytest.raises(ValueError, match="no ground truth"):
        breakdown(frame, np.ones((4, 8)))
