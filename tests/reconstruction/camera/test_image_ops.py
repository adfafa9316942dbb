"""The shared equirect image and rotation operations (reconstruction.camera.image_ops): periodic padding and
filters, differences, grey conversion, axis-angle rotations, the Tukey reweighting."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from reconstruction.camera.image_ops import (
    axis_angle_matrix,
    central_differences,
    grey,
    local_contrast,
    periodic_box_filter,
    periodic_filter,
    periodic_gaussian_blur,
    periodic_pad,
    robust_scale,
    rotation_angle_deg,
    rotation_vector_matrix,
    sobel_gradient,
    tukey_weights,
    vector_angle_deg,
)


def _image(h: int = 12, w: int = 20, channels: int = 0, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    shape = (h, w, channels) if channels else (h, w)
    return rng.uniform(0.0, 255.0, shape).astype(np.float32)


def test_periodic_pad_wraps_longitude_and_fills_rows_by_mode():
    x = _image(5, 8)
    p = periodic_pad(x, 3)
    assert p.shape == (5, 14)
    np.testing.assert_array_equal(p[:, :3], x[:, -3:])
    np.testing.assert_array_equal(p[:, 3:-3], x)
    np.testing.assert_array_equal(p[:, -3:], x[:, :3])
    for mode in ("edge", "reflect", "symmetric", "constant"):
        q = periodic_pad(x, 2, 2, mode)
        assert q.shape == (9, 12) and q.flags.c_contiguous
        np.testing.assert_array_equal(q[:, 2:-2], np.pad(x, ((2, 2), (0, 0)), mode=mode))
        np.testing.assert_array_equal(q[:, :2], q[:, -4:-2])  # the corners wrap as the rows do
    np.testing.assert_array_equal(periodic_pad(x, 1, 1, "edge")[0, 1:-1], x[0])
    np.testing.assert_array_equal(periodic_pad(x, 1, 1, "reflect")[0, 1:-1], x[1])
    np.testing.assert_array_equal(periodic_pad(x, 1, 1, "constant")[0], np.zeros(10, np.float32))


def test_periodic_pad_keeps_dtype_channels_and_wraps_again_past_the_width():
    rgb = (_image(4, 6, 3) % 256).astype(np.uint8)
    p = periodic_pad(rgb, 2)
    assert p.dtype == np.uint8 and p.shape == (4, 10, 3)
    np.testing.assert_array_equal(p[:, 0], rgb[:, 4])
    wide = periodic_pad(rgb, 8)
    np.testing.assert_array_equal(wide[:, :8], rgb[:, np.arange(-8, 0) % 6])
    assert periodic_pad(rgb, 0) is rgb
    with pytest.raises(ValueError, match="row mode"):
        periodic_pad(rgb, 1, 1, "wrap")
    with pytest.raises(ValueError, match=">= 0"):
        periodic_pad(rgb, -1)


def test_periodic_filters_commute_with_a_longitude_shift():
    """A filter on the sphere has no seam: shifting the image by k columns shifts the result by k columns (the
    Gaussian's padding covers OpenCV's kernel radius of 4 sigma for float images)."""
    x = _image(16, 32, seed=1)
    shifted = np.roll(x, 7, axis=1)
    for f in (lambda a: periodic_gaussian_blur(a, 1.5, cols=7),
              lambda a: periodic_gaussian_blur(a, 2.0, cols=9, rows=6, row_mode="reflect"),
              lambda a: periodic_box_filter(a, 5),
              lambda a: periodic_box_filter(a, 3, normalize=False, border=cv2.BORDER_REPLICATE),
              lambda a: sobel_gradient(a)[0],
              lambda a: central_differences(a)[0]):
        np.testing.assert_allclose(f(shifted), np.roll(f(x), 7, axis=1), rtol=0, atol=1e-3)


def test_blur_and_box_of_a_constant_are_the_constant():
    x = np.full((10, 24), 42.5, np.float32)
    np.testing.assert_allclose(periodic_gaussian_blur(x, 2.0), x, rtol=0, atol=1e-4)
    np.testing.assert_allclose(periodic_gaussian_blur(x, 1.0, cols=3, rows=3, ksize=7), x, rtol=0, atol=1e-4)
    np.testing.assert_allclose(periodic_box_filter(x, 5), x, rtol=0, atol=1e-4)
    np.testing.assert_allclose(periodic_box_filter(x, 3, normalize=False, border=cv2.BORDER_REPLICATE), 9 * x,
                               rtol=0, atol=1e-3)
    assert periodic_gaussian_blur(x, 0.0) is x


def test_box_filter_sums_the_window_across_the_seam():
    x = np.zeros((3, 10), np.float32)
    x[1, 0] = 1.0
    s = periodic_box_filter(x, 3, normalize=False)
    np.testing.assert_array_equal(np.flatnonzero(s[1]), [0, 1, 9])  # column 0's window holds columns 9, 0, 1


def test_periodic_filter_crops_to_the_input():
    x = _image(6, 9)
    out = periodic_filter(x, 2, lambda p: p + 1.0, rows=1, row_mode="edge")
    np.testing.assert_array_equal(out, x + 1.0)


def test_central_differences_of_a_ramp():
    v, u = np.mgrid[0:6, 0:10].astype(np.float64)
    dx, dy = central_differences(3.0 * u + 2.0 * v)
    np.testing.assert_allclose(dx[:, 1:-1], 3.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(dx[:, 0], 0.5 * (3.0 - 27.0), rtol=0, atol=1e-12)  # wraps: (u=1) - (u=9)
    np.testing.assert_allclose(dy[1:-1], 2.0, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(dy[[0, -1]], 0.0)
    dx, _ = central_differences(3.0 * u, wrap=False)
    np.testing.assert_array_equal(dx[:, [0, -1]], 0.0)
    dx, dy = central_differences(3.0 * u + 2.0 * v, step=2, scale=1.0)
    np.testing.assert_allclose(dx[:, 2:-2], 12.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(dy[2:-2], 8.0, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(dy[[0, 1, -2, -1]], 0.0)


def test_sobel_gradient_reads_a_ramp_slope():
    v, u = np.mgrid[0:8, 0:16].astype(np.float32)
    dx, dy = sobel_gradient(0.5 * u + 1.5 * v)
    assert dx.dtype == np.float32 and dx.shape == (8, 16)
    np.testing.assert_allclose(dx[:, 1:-1], 0.5, rtol=0, atol=1e-5)
    np.testing.assert_allclose(dy[1:-1], 1.5, rtol=0, atol=1e-5)
    np.testing.assert_allclose(dy[0], 0.75, rtol=0, atol=1e-5)  # the pole row replicated: half a step
    assert abs(float(dx[3, 0])) > 1.0  # the seam of a ramp is an edge when columns wrap ...
    dx, _ = sobel_gradient(0.5 * u + 1.5 * v, wrap=False)
    np.testing.assert_allclose(dx[:, 0], 0.25, rtol=0, atol=1e-5)  # ... and half a step when they do not


def test_grey_modes():
    rgb = np.array([[[255, 0, 0], [0, 255, 0], [0, 0, 255], [10, 20, 30]]], np.uint8)
    np.testing.assert_array_equal(grey(rgb), cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY))
    assert grey(rgb).dtype == np.uint8
    np.testing.assert_allclose(grey(rgb, "bt601")[0], [76.245, 149.685, 29.07, 0.299 * 10 + 0.587 * 20 + 0.114 * 30],
                               rtol=0, atol=1e-4)
    np.testing.assert_allclose(grey(rgb, "mean")[0], [85.0, 85.0, 85.0, 20.0], rtol=0, atol=1e-5)
    lin = np.array([[[1.0, 1.0, 1.0], [0.0, 1.0, 0.0]]])
    np.testing.assert_allclose(grey(lin, "bt709")[0], [1.0, 0.7152], rtol=0, atol=1e-12)
    plane = rgb[..., 0]
    assert grey(plane, "bt601") is plane
    with pytest.raises(ValueError, match="grey mode"):
        grey(rgb, "luma")


def test_rotation_vector_matrix_is_a_proper_rotation_matching_known_cases():
    for omega in ([0.3, -0.2, 0.9], [1e-9, 0.0, 0.0], [2.0, 1.0, -1.0]):
        m = rotation_vector_matrix(np.array(omega))
        np.testing.assert_allclose(m @ m.T, np.eye(3), rtol=0, atol=1e-12)
        assert np.linalg.det(m) == pytest.approx(1.0, abs=1e-12)
        np.testing.assert_allclose(m, cv2.Rodrigues(np.array(omega, np.float64))[0], rtol=0, atol=1e-12)
    quarter = rotation_vector_matrix(np.array([0.0, 0.0, math.pi / 2]))
    np.testing.assert_allclose(quarter @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], rtol=0, atol=1e-12)  # x -> y about +z
    np.testing.assert_array_equal(rotation_vector_matrix(np.zeros(3)), np.eye(3))


def test_axis_angle_matrix_about_vectors_and_coordinate_axes():
    m = axis_angle_matrix([0.0, 0.0, 5.0], math.pi / 2)  # any length: normalised
    np.testing.assert_allclose(m, rotation_vector_matrix(np.array([0.0, 0.0, math.pi / 2])), rtol=0, atol=1e-15)
    for axis in range(3):
        for angle in (0.3, -2.5, math.pi):
            exact = axis_angle_matrix(axis, angle)
            np.testing.assert_allclose(exact, axis_angle_matrix(np.eye(3)[axis], angle), rtol=0, atol=1e-15)
            assert exact[axis, axis] == 1.0 and np.count_nonzero(exact) == 5
    np.testing.assert_allclose(axis_angle_matrix(0, math.pi / 2) @ [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], rtol=0,
                               atol=1e-15)  # y -> z about +x


def test_angles_between_vectors_and_rotations():
    assert vector_angle_deg([1.0, 0.0, 0.0], [0.0, 3.0, 0.0]) == pytest.approx(90.0, abs=1e-12)
    assert vector_angle_deg([1.0, 1.0, 0.0], [2.0, 2.0, 0.0]) == pytest.approx(0.0, abs=1e-5)  # acos at 1
    assert vector_angle_deg([1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]) == pytest.approx(180.0, abs=1e-12)
    a = axis_angle_matrix([1.0, 2.0, 3.0], 0.4)
    b = axis_angle_matrix([1.0, 2.0, 3.0], 0.4 + math.radians(7.0)) @ np.eye(3)
    assert rotation_angle_deg(a, b) == pytest.approx(7.0, abs=1e-9)


def test_robust_scale_and_floor_modes():
    rng = np.random.default_rng(3)
    r = rng.normal(0.0, 2.0, 200000)
    assert robust_scale(r) == pytest.approx(2.0, rel=0.01)
    assert robust_scale(np.zeros(10), 1e-6, "add") == 1e-6
    assert robust_scale(np.full(10, 3.0), 0.5, "max") == 0.5
    assert robust_scale(r, 0.5, "max") == robust_scale(r)
    with pytest.raises(ValueError, match="floor_mode"):
        robust_scale(r, 1.0, "min")


def test_tukey_weights_shape():
    w = tukey_weights(np.array([0.0, 1.0, -2.0, 4.685, 10.0]), 4.685, 1.0)
    np.testing.assert_allclose(w, [1.0, (1 - (1 / 4.685) ** 2) ** 2, (1 - (2 / 4.685) ** 2) ** 2, 0.0, 0.0], rtol=0,
                               atol=1e-12)


def test_tukey_refit_ignores_a_planted_outlier():
    """Iteratively reweighted least squares of a line with one gross outlier: the Tukey weights drop it."""
    rng = np.random.default_rng(5)
    x = np.linspace(0.0, 1.0, 50)
    y = 2.0 + 3.0 * x + rng.normal(0.0, 0.01, x.size)
    y[17] += 40.0
    design = np.stack([np.ones_like(x), x], axis=1)
    coef = np.linalg.lstsq(design, y, rcond=None)[0]
    assert abs(coef[0] - 2.0) > 0.3  # the plain fit is pulled away
    for _ in range(10):
        res = y - design @ coef
        w = tukey_weights(res, 4.685, robust_scale(res, 1e-6, "add"))
        coef = np.linalg.solve(design.T @ (design * w[:, None]), design.T @ (w * y))
    assert w[17] == 0.0
    np.testing.assert_allclose(coef, [2.0, 3.0], rtol=0, atol=0.02)


def test_local_contrast_is_the_windowed_standard_deviation_and_wraps_in_longitude():
    h, w = 64, 128
    flat = np.full((h, w), 100.0, np.float32)
    np.testing.assert_allclose(local_contrast(flat, 3.0), 0.0, atol=1e-3)
    # a fine checkerboard of +-a has standard deviation a in any window much wider than its period
    yy, xx = np.mgrid[0:h, 0:w]
    board = (100.0 + 10.0 * np.where((yy + xx) % 2 == 0, 1.0, -1.0)).astype(np.float32)
    np.testing.assert_allclose(local_contrast(board, 3.0)[8:-8], 10.0, rtol=0.02)
    # a step at the seam (column 0 | W-1) looks like the same step in the middle of the image
    step = np.where(xx < w // 2, 0.0, 50.0).astype(np.float32)
    c = local_contrast(step, 3.0)
    np.testing.assert_allclose(c[:, 0], c[:, w // 2], atol=1e-3)
    assert c[:, 0].min() > 20.0 and c[:, w // 4].max() < 1e-2
