"""Visibility from the hypothesis in the sweep's cost: the range buffer of a pair's other camera against the exact
geometry of a sphere, and the cost of the true distance where one camera is occluded."""

from __future__ import annotations

import numpy as np
import pytest

from reconstruction.camera.resample import rotation_maps
from reconstruction.sweep.cost import CostParams, build_cost_volume, inverse_distances, visibility_buffer
from reports.regions import occluded_from
from tests.helpers import make_synthetic_frame


def test_the_range_buffer_of_a_sphere_about_c_is_its_exact_range_from_k():
    """C's estimate is a sphere of radius D about C; the other camera K is b along the rectified +Z.  Every cell
    the buffer fills holds the range from K to where K's ray through the cell's row centre meets the sphere,
    ``t = -b cos(theta') + sqrt(D^2 - b^2 sin^2(theta'))``, within what one row of K changes it (the buffer keeps
    the nearest of the C pixels landing in the 2 x 2 cells around them)."""
    w, h, d, b = 200, 100, 3.0, 0.4
    rot = np.eye(3)
    ur, vr = (a.astype(np.float32) for a in rotation_maps(w, h, rot, rot))
    zbuf = visibility_buffer(np.full((h, w), d), ur, vr, b, w, h)
    assert zbuf.shape == (w, h) and zbuf.dtype == np.float32
    filled = np.isfinite(zbuf)
    assert filled.mean() > 0.95  # the sphere covers K's whole view: only the rows beyond its poles stay empty
    theta2 = np.pi * (np.arange(h) + 0.5) / h
    t = -b * np.cos(theta2) + np.sqrt(d * d - (b * np.sin(theta2)) ** 2)
    per_row = b * np.pi / h  # |dt/dtheta'| <= b (D > b), times one row
    err = np.abs(zbuf - t[None, :])[filled]
    assert err.max() <= 1.5 * per_row + 1e-4, err.max()
    # nothing of the estimate lands beyond it: a buffer of missing distances is empty
    assert not np.isfinite(visibility_buffer(np.full((h, w), np.nan), ur, vr, b, w, h)).any()


@pytest.fixture(scope="module")
def box():
    return make_synthetic_frame(400)


def _true_label_share(frame, params, mask, estimate=None):
    """Share of the pixels in ``mask`` whose lowest cost is within 2 labels of their true inverse distance."""
    cost, _ = build_cost_volume(frame, params, estimate=estimate)
    q = inverse_distances(params)
    best = q[np.argmin(cost, axis=2)]
    gt = frame.distance["C"]
    return float(np.mean(np.abs(best[mask] - 1.0 / gt[mask]) <= 2 * (q[1] - q[0])))


def test_an_occluded_pair_does_not_vote_for_the_true_distance(box):
    """With the true distances as the estimate, C's pixels that R cannot see find their distance from U alone:
    the cost's minimum is at the true distance in more of them than when R votes too (measured on the 121 such
    pixels of the 400x200 synthetic box: 0.31 without, 0.57 with); elsewhere it hardly changes (0.878 both)."""
    params = CostParams(levels=96, box_px=1)
    occluded = occluded_from(box, "R")
    gt = box.distance["C"]
    seen = np.isfinite(gt) & ~occluded & ~occluded_from(box, "U")
    assert occluded.sum() > 50
    vis = CostParams(levels=96, box_px=1, occlusion=0.05)
    before, after = _true_label_share(box, params, occluded), _true_label_share(box, vis, occluded, gt)
    assert after >= before + 0.15, (before, after)
    assert abs(_true_label_share(box, vis, seen, gt) - _true_label_share(box, params, seen)) <= 0.02
    # without an estimate the occlusion parameter changes nothing
    np.testing.assert_array_equal(build_cost_volume(box, vis)[0], build_cost_volume(box, params)[0])


def test_occlusion_parameters_are_checked():
    with pytest.raises(ValueError, match="occlusion"):
        CostParams(occlusion=-0.1)
    with pytest.raises(ValueError, match="occlusion_min_share"):
        CostParams(occlusion_min_share=1.5)
