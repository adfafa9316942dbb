"""Filling distance maps and fusing the pairs' distances (``reconstruction.refine.fill``)."""

import numpy as np
import pytest

from reconstruction.refine.fill import agreed_distance, fill_edge_aware, fill_invalid, fuse_average


def test_fill_invalid_interpolates_holes():
    d = np.full((40, 80), 3.0)
    d[:, 40:] = 5.0
    valid = np.ones_like(d, bool)
    valid[10:14, 10:14] = False
    valid[20:22, 60:62] = False
    d_bad = np.where(valid, d, 99.0)
    out = fill_invalid(d_bad, valid)
    np.testing.assert_allclose(out[10:14, 10:14], 3.0, atol=1e-6)
    np.testing.assert_allclose(out[20:22, 60:62], 5.0, atol=1e-6)
    assert np.array_equal(out[valid], d[valid])


def test_agreed_distance_keeps_only_pixels_both_pairs_triangulate_alike():
    d_u = np.array([2.0, 2.0, 2.0, 2.0, 5.0, -1.0])
    d_r = np.array([2.0, 2.09, 2.11, 2.0, 5.2, -1.0])
    v_u = np.array([True, True, True, False, True, True])
    v_r = np.ones(6, bool)
    got = agreed_distance([d_u, d_r], [v_u, v_r], 0.05)
    # ln(2.09 / 2) = 0.044 agrees, ln(2.11 / 2) = 0.054 does not; an invalid or non-positive pair never does
    np.testing.assert_allclose(got[:2], [2.0, 2.045], rtol=1e-12)
    assert np.isnan(got[2:4]).all() and np.isnan(got[5])
    np.testing.assert_allclose(got[4], 5.1, rtol=1e-12)  # ln(5.2 / 5) = 0.039


def test_fuse_average_takes_the_valid_pairs_and_fills_where_neither_is():
    d_u = np.array([2.0, 2.0, 9.0, 9.0] * 4)
    d_r = np.array([4.0, 9.0, 3.0, 9.0] * 4)
    v_u = np.array([True, True, False, False] * 4)
    v_r = np.array([True, False, True, False] * 4)
    got = fuse_average([d_u, d_r], [v_u, v_r], (4, 4))
    np.testing.assert_allclose(got.reshape(4, 4)[:, :3], [[3.0, 2.0, 3.0]] * 4, rtol=1e-12)
    # no valid pair in column 3: filled from the neighbours (2.0 to 3.0), never the invalid pairs' 9.0
    assert (got.reshape(4, 4)[:, 3] >= 2.0).all() and (got.reshape(4, 4)[:, 3] <= 3.0).all()


def test_fill_edge_aware_interpolates_inverse_or_log_distance_and_stops_at_image_edges():
    # a 1 m and a 4 m region, a gap between them on a flat image: the fill of the gap's middle lies between the
    # two, at the harmonic-like mean in inverse distance and the geometric-like mean in log distance
    d = np.where(np.arange(120)[None, :] < 60, 1.0, 4.0) * np.ones((40, 1))
    valid = np.ones(d.shape, bool)
    valid[:, 50:70] = False
    flat = np.full((40, 120, 3), 128, np.uint8)
    inverse = fill_edge_aware(np.where(valid, d, 99.0), valid, flat, 200.0, 8.0)
    log = fill_edge_aware(np.where(valid, d, 99.0), valid, flat, 200.0, 8.0, space="log")
    mid_inverse, mid_log = inverse[20, 59:61].mean(), log[20, 59:61].mean()
    assert 1.0 < mid_inverse < mid_log < 4.0
    np.testing.assert_allclose(mid_inverse, 1.6, rtol=0.1)  # 1 / mean(1, 1 / 4)
    np.testing.assert_allclose(mid_log, 2.0, rtol=0.1)  # exp(mean(ln 1, ln 4))
    # an image edge where the distance jumps: the gap takes the distance of its own side in either space
    image = np.where(np.arange(120)[None, :, None] < 60, 40, 220).astype(np.uint8) * np.ones((40, 1, 3), np.uint8)
    for space in ("inverse", "log"):
        out = fill_edge_aware(np.where(valid, d, 99.0), valid, image, 200.0, 8.0, space=space)
        np.testing.assert_allclose(out[:, 52:58], 1.0, rtol=0.03)
        np.testing.assert_allclose(out[:, 62:68], 4.0, rtol=0.03)
    with pytest.raises(ValueError, match="unknown fill space 'linear'"):
        fill_edge_aware(d, valid, flat, 200.0, 8.0, space="linear")
