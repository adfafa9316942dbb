"""DeepMatching on synthetic textured images with known motion: large shifts across the equirect seam, rotations."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from reconstruction.flow.deepmatching import DeepMatchingParams, deep_matching, deep_matching_both, pixel_descriptors

H, W = 64, 128
FULL = DeepMatchingParams(downscale=0)  # the test images are small: match at full resolution


def texture(h: int, w: int, seed: int, blob_px: int = 4) -> np.ndarray:
    """(h, w, 3) uint8 smooth random texture (random values on a blob_px grid, bicubic upsampling)."""
    rng = np.random.default_rng(seed)
    x = rng.random((h // blob_px, w // blob_px, 3)).astype(np.float32)
    return np.clip(cv2.resize(x, (w, h), interpolation=cv2.INTER_CUBIC) * 255, 0, 255).astype(np.uint8)


def test_descriptors_are_unit_nonnegative_and_periodic():
    img = texture(H, W, 0)
    gray = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY).astype(np.float32)
    d = pixel_descriptors(gray, FULL)
    assert d.shape == (H, W, 9) and d.min() >= 0
    np.testing.assert_allclose(np.linalg.norm(d, axis=2), 1.0, atol=1e-5)
    # wrap: the descriptor of a horizontally rolled image is the rolled descriptor (within float rounding)
    d_roll = pixel_descriptors(np.roll(gray, 37, axis=1), FULL)
    np.testing.assert_allclose(d_roll, np.roll(d, 37, axis=1), atol=1e-4)


@pytest.mark.slow
def test_finds_a_60_px_shift_across_the_seam():
    """Image 1 is image 0 moved 60 px right (wrapping: half the patches cross the seam) and 3 px down.
    At least 90 % of the matches lie within 2 px of the true motion and at least 70 % of the patches match."""
    img0 = texture(H, W, 1)
    img1 = np.roll(np.roll(img0, 60, axis=1), 3, axis=0)
    img1[:3] = img0[:1]  # the rows rolled in from the bottom are not a continuation of the sphere: blank them
    m = deep_matching(img0, img1, FULL)
    ex = (m.x1 - m.x0 - 60 + W / 2) % W - W / 2
    err = np.hypot(ex, m.y1 - m.y0 - 3)
    n_patches = (H // 8) * (W // 8)
    assert m.x0.size >= 0.7 * n_patches
    assert np.mean(err <= 2.0) >= 0.9
    assert np.any(m.x0 + 60 >= W)  # matches that cross the seam exist and are counted above


@pytest.mark.slow
def test_finds_a_rotation_and_a_large_shift():
    """Image 1 is image 0 rotated by 8 degrees about its centre and moved 20 px (no wrap): matches whose true
    target lies inside the image are within 2 px for at least 90 % of them."""
    h, w = 96, 128
    img0 = texture(h, w, 2, blob_px=6)
    ang = np.deg2rad(8.0)
    c, s = np.cos(ang), np.sin(ang)
    a = np.array([[c, -s, 0.0], [s, c, 0.0]])
    centre = np.array([(w - 1) / 2, (h - 1) / 2])
    a[:, 2] = centre - a[:, :2] @ centre + np.array([20.0, 0.0])
    img1 = cv2.warpAffine(img0, a, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    m = deep_matching(img0, img1, DeepMatchingParams(downscale=0, wrap=False))
    true = np.stack([m.x0, m.y0], axis=1) @ a[:, :2].T + a[:, 2]
    inside = (true[:, 0] >= 8) & (true[:, 0] <= w - 9) & (true[:, 1] >= 8) & (true[:, 1] <= h - 9)
    err = np.hypot(m.x1 - true[:, 0], m.y1 - true[:, 1])[inside]
    assert inside.sum() >= 40
    assert np.mean(err <= 2.0) >= 0.9


@pytest.mark.slow
def test_both_ways_and_deterministic():
    img0 = texture(H, W, 3)
    img1 = np.roll(img0, -25, axis=1)
    f1, b1 = deep_matching_both(img0, img1, FULL)
    f2, b2 = deep_matching_both(img0, img1, FULL)
    for x, y in ((f1, f2), (b1, b2)):
        for k in ("x0", "y0", "x1", "y1", "score"):
            np.testing.assert_array_equal(getattr(x, k), getattr(y, k))
    # the backward matches undo the forward motion
    ex = (b1.x1 - b1.x0 - 25 + W / 2) % W - W / 2
    assert np.mean(np.hypot(ex, b1.y1 - b1.y0) <= 2.0) >= 0.9
