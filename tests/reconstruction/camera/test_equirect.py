"""Equirectangular camera model: directions, round trips, seam, poles, analytic derivative."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from reconstruction.camera.equirect import (
    bearing_grid,
    bearing_to_pixel,
    pixel_to_bearing,
    project,
    project_with_derivative,
    wrap_pixel,
)

W, H = 64, 32


def test_image_centre_looks_forward():
    # the centre of the image is the corner between pixels (W/2 - 1, H/2 - 1) and (W/2, H/2): u + 0.5 = W/2
    b = pixel_to_bearing(W / 2 - 0.5, H / 2 - 0.5, W, H)
    np.testing.assert_allclose(b, [0, 1, 0], atol=1e-12)


def test_three_quarter_width_looks_right_and_quarter_left():
    np.testing.assert_allclose(pixel_to_bearing(0.75 * W - 0.5, H / 2 - 0.5, W, H), [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(pixel_to_bearing(0.25 * W - 0.5, H / 2 - 0.5, W, H), [-1, 0, 0], atol=1e-12)


def test_top_row_looks_up_bottom_row_down():
    top = pixel_to_bearing(np.arange(W), np.zeros(W), W, H)
    bottom = pixel_to_bearing(np.arange(W), np.full(W, H - 1), W, H)
    # the first row's centre is half a row (pi / (2H) rad) below the zenith
    np.testing.assert_allclose(top[:, 2], np.cos(np.pi / (2 * H)), atol=1e-12)
    np.testing.assert_allclose(bottom[:, 2], -np.cos(np.pi / (2 * H)), atol=1e-12)


def test_left_and_right_edges_are_the_backward_meridian():
    left = pixel_to_bearing(-0.5, H / 2 - 0.5, W, H)
    right = pixel_to_bearing(W - 0.5, H / 2 - 0.5, W, H)
    np.testing.assert_allclose(left, [0, -1, 0], atol=1e-12)
    np.testing.assert_allclose(right, [0, -1, 0], atol=1e-12)


def test_hand_computed_pixel():
    # pixel (0, 0): lam = 2 pi * 0.5 / W - pi, phi = pi/2 - pi * 0.5 / H
    lam, phi = 2 * np.pi * 0.5 / W - np.pi, np.pi / 2 - np.pi * 0.5 / H
    expect = [np.cos(phi) * np.sin(lam), np.cos(phi) * np.cos(lam), np.sin(phi)]
    np.testing.assert_allclose(pixel_to_bearing(0, 0, W, H), expect, atol=1e-15)


def test_grid_round_trip_every_pixel():
    b = bearing_grid(W, H)
    u, v = bearing_to_pixel(b, W, H)
    vv, uu = np.mgrid[0:H, 0:W]
    np.testing.assert_allclose(u, uu, atol=1e-9)
    np.testing.assert_allclose(v, vv, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(b, axis=-1), 1.0, atol=1e-12)


@pytest.mark.parametrize("w, h", [(W, H), (7, 3), (360, 180)])
def test_grid_is_pixel_to_bearing_of_every_pixel(w, h):
    """The separable grid (longitude by column, latitude by row) against the bearing of each pixel, with and without
    a rotation (1e-15: the same values up to rounding)."""
    vv, uu = np.mgrid[0:h, 0:w]
    rot = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(bearing_grid(w, h), pixel_to_bearing(uu, vv, w, h), rtol=0, atol=1e-15)
    np.testing.assert_allclose(bearing_grid(w, h, rot), pixel_to_bearing(uu, vv, w, h) @ rot.T, rtol=0, atol=1e-15)
    assert bearing_grid(w, h, dtype=np.float32).dtype == np.float32


@settings(max_examples=200, deadline=None)
@given(st.floats(-0.49, W - 0.51), st.floats(-0.49, H - 0.51))
def test_round_trip_continuous(u, v):
    uu, vv = bearing_to_pixel(pixel_to_bearing(u, v, W, H), W, H)
    assert abs(uu - u) < 1e-9 and abs(vv - v) < 1e-9


def test_rotation_maps_camera_axes_to_world():
    rot = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])  # camera forward (+Y) looks along world -X
    b = bearing_grid(W, H, rotation=rot)
    centre = 0.5 * (b[H // 2 - 1, W // 2 - 1] + b[H // 2, W // 2])
    np.testing.assert_allclose(centre / np.linalg.norm(centre), [-1, 0, 0], atol=1e-12)


def test_project_known_points():
    pos = np.array([1.0, 2.0, 0.5])
    u, v = project(pos + np.array([[0, 5.0, 0], [3.0, 0, 0], [0, 0, 2.0]]), pos, np.eye(3), W, H)
    np.testing.assert_allclose(u[:2], [W / 2 - 0.5, 0.75 * W - 0.5], atol=1e-12)
    np.testing.assert_allclose(v[:2], H / 2 - 0.5, atol=1e-12)
    assert v[2] == pytest.approx(-0.5, abs=1e-12)  # straight up: the top edge of the image


def test_wrap_pixel_seam_and_poles():
    u, v = wrap_pixel(np.array([W + 0.25, -1.0, 10.0, 10.0]), np.array([5.0, 5.0, -1.5, H + 0.5]), W, H)
    np.testing.assert_allclose(u, [0.25, W - 1.0, 10 + W / 2, 10 + W / 2], atol=1e-12)
    np.testing.assert_allclose(v, [5.0, 5.0, 0.5, H - 1.5], atol=1e-12)


@settings(max_examples=100, deadline=None)
@given(st.floats(-3 * W, 3 * W), st.floats(-2 * H, 3 * H))
def test_wrap_pixel_preserves_the_bearing(u, v):
    """A pixel pushed across the seam or a pole is the same direction after wrapping."""
    # continue the latitude past the pole along the great circle: build the bearing from unwrapped angles
    lam = 2 * np.pi * (u + 0.5) / W - np.pi
    phi = np.pi / 2 - np.pi * (v + 0.5) / H
    b = np.array([np.cos(phi) * np.sin(lam), np.cos(phi) * np.cos(lam), np.sin(phi)])
    uw, vw = wrap_pixel(u, v, W, H)
    assert -0.5 <= uw < W - 0.5 and -0.5 <= vw <= H - 0.5
    np.testing.assert_allclose(pixel_to_bearing(uw, vw, W, H), b, atol=1e-9)


def test_derivative_matches_finite_differences():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(500, 3))
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    d = rng.uniform(0.5, 8.0, size=500)
    origin = np.array([0.2, -0.1, 1.3])
    pos = origin + np.array([0.4, 0.0, 0.0])
    rot = np.array([[np.cos(0.3), -np.sin(0.3), 0], [np.sin(0.3), np.cos(0.3), 0], [0, 0, 1]])
    u, v, du, dv = project_with_derivative(origin, a, d, pos, rot, 1000, 500)
    h = 1e-6
    u1, v1, _, _ = project_with_derivative(origin, a, d + h, pos, rot, 1000, 500)
    u0, v0, _, _ = project_with_derivative(origin, a, d - h, pos, rot, 1000, 500)
    # skip the rare samples whose finite difference straddles the seam
    du_fd = (np.mod(u1 - u0 + 500, 1000) - 500) / (2 * h)
    np.testing.assert_allclose(du, du_fd, rtol=1e-5, atol=1e-3)  # pixels per metre
    np.testing.assert_allclose(dv, (v1 - v0) / (2 * h), rtol=1e-5, atol=1e-3)
    uu, vv = project(origin + d[:, None] * a, pos, rot, 1000, 500)
    np.testing.assert_allclose(u, uu, atol=1e-9)
    np.testing.assert_allclose(v, vv, atol=1e-9)
