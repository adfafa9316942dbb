"""No matching preference where C shows no texture above its noise (``CostParams.flat_contrast``): which pixels,
what their costs become, and that nothing else changes."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from reconstruction.sweep.cost import CostParams, build_cost_volume, flatten_untextured, untextured
from tests.helpers import make_synthetic_frame


def test_flatten_gives_the_masked_pixels_the_floor_of_their_mean_and_leaves_the_rest():
    rng = np.random.default_rng(3)
    cost = rng.integers(0, 481, (12, 20, 11), dtype=np.uint16)
    mask = rng.random((12, 20)) < 0.4
    before = cost.copy()
    flatten_untextured(cost, 8, mask)
    means = before[..., :8].astype(np.int64).sum(axis=2) // 8
    np.testing.assert_array_equal(cost[mask][:, :8], np.repeat(means[mask][:, None], 8, axis=1))
    np.testing.assert_array_equal(cost[~mask], before[~mask])
    np.testing.assert_array_equal(cost[..., 8:], before[..., 8:])  # plane and wall labels are not touched
    # half way: the mean's share 0.5, each cost's the rest, floored
    half = before.copy()
    flatten_untextured(half, 8, mask, 0.5)
    expected = np.floor(0.5 * before[..., :8] + 0.5 * (before[..., :8].astype(np.int64).sum(axis=2) / 8)[..., None])
    np.testing.assert_array_equal(half[mask][:, :8], expected[mask])
    np.testing.assert_array_equal(half[~mask], before[~mask])
    unchanged = before.copy()
    flatten_untextured(unchanged, 8, mask, 0.0)
    np.testing.assert_array_equal(unchanged, before)
    with pytest.raises(ValueError, match="within"):
        flatten_untextured(cost, 8, mask, 1.5)
    with pytest.raises(ValueError, match="do not fit"):
        flatten_untextured(cost, 8, mask[:, :10])
    with pytest.raises(ValueError, match="do not fit"):
        flatten_untextured(cost, 12, mask)


def _image(amplitude: float, noise: float, seed: int = 0) -> np.ndarray:
    """(100, 200, 3) uint8: a gray of 120 whose right half carries a sinusoid of ``amplitude`` gray levels (period 8
    px), plus white noise of ``noise`` gray levels (the same in the three channels)."""
    rng = np.random.default_rng(seed)
    x = np.arange(200)
    g = 120.0 + np.where(x >= 100, amplitude * np.sin(2 * np.pi * x / 8.0), 0.0)[None, :]
    g = g + noise * rng.standard_normal((100, 200))
    return np.repeat(np.clip(np.rint(g), 0, 255).astype(np.uint8)[..., None], 3, axis=2)


def test_untextured_is_below_the_threshold_times_the_noise():
    params = CostParams(flat_contrast=1.5)
    left, right = np.s_[10:-10, 10:90], np.s_[10:-10, 110:190]
    # a texture of 6 gray levels above noise of 1: the plain half is marked, the textured half is not
    quiet = untextured(_image(6.0, 1.0), params)
    assert quiet.dtype == bool and quiet.shape == (100, 200)
    assert quiet[left].mean() > 0.95 and quiet[right].mean() == 0.0
    # the same texture under noise of 8 is no texture above the noise: both halves are marked
    loud = untextured(_image(6.0, 8.0), params)
    assert loud[left].mean() > 0.95 and loud[right].mean() > 0.9
    # off: nothing marked; a noise-free plain image is marked through the least noise assumed, not without it
    assert not untextured(_image(6.0, 1.0), CostParams()).any()
    plain = np.full((100, 200, 3), 90, np.uint8)
    assert untextured(plain, params).all()
    assert not untextured(plain, dataclasses.replace(params, flat_min_noise=0.0)).any()


def test_the_parameters_are_checked():
    for bad in ({"flat_contrast": -1.0}, {"flat_sigma_px": 0.0}, {"flat_min_noise": -0.1}, {"flat_weight": 1.2},
                {"flat_weight": -0.5}):
        with pytest.raises(ValueError, match="flat_"):
            CostParams(**bad)


def test_the_cost_volume_is_flat_on_plain_pixels_and_unchanged_elsewhere():
    frame = make_synthetic_frame(200)
    # a plain patch in C's image, so that some pixels have no texture whatever the scene's
    frame.images["C"][30:60, 40:100] = 128
    off = CostParams(levels=48, box_px=1)
    on = dataclasses.replace(off, flat_contrast=1.0)
    mask = untextured(frame.images["C"], on)
    assert mask[40:50, 52:88].all() and 0 < mask.mean() < 0.9  # the patch, 10 px (5 sigma) in from its edges
    base, _ = build_cost_volume(frame, off, extra_labels=3)
    flat, _ = build_cost_volume(frame, on, extra_labels=3)
    sphere = flat[..., :48]
    assert (sphere[mask] == sphere[mask][:, :1]).all()
    np.testing.assert_array_equal(sphere[mask][:, 0], base[..., :48][mask].astype(np.int64).sum(axis=1) // 48)
    np.testing.assert_array_equal(sphere[~mask], base[..., :48][~mask])
