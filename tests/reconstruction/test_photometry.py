"""Photometric self-calibration (reconstruction.photometry): the sRGB transfer, the field's basis, the robust fit, and
U's and R's images corrected to C's exposure, white balance and fall-off on exact ray-cast frames."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from reconstruction.camera.equirect import bearing_grid
from reconstruction.camera.image_ops import robust_scale, tukey_weights
from reconstruction.flow.backends import FlowBackend, builtin_flow, get_flow
from reconstruction.methods.presets import fused_mirror
from reconstruction.photometry import (
    NO_CALIBRATION,
    FrameView,
    PhotometricParams,
    _irls,
    align_images,
    basis,
    fit_gain,
    linear_to_srgb,
    srgb_to_linear,
)
from tests.helpers import make_synthetic_frame


def test_srgb_round_trip_and_known_values():
    x = np.arange(256, dtype=np.uint8)
    np.testing.assert_array_equal(linear_to_srgb(srgb_to_linear(x)), x)
    assert srgb_to_linear(np.uint8(0)) == 0.0 and srgb_to_linear(np.uint8(255)) == pytest.approx(1.0, abs=1e-12)
    assert srgb_to_linear(np.uint8(128)) == pytest.approx(0.2158605, abs=1e-6)  # IEC 61966-2-1 at 128/255
    assert linear_to_srgb(np.array([np.nan, -1.0, 2.0])).tolist() == [0, 0, 255]


def test_basis_columns_and_the_seam_kink():
    b = bearing_grid(16, 8)
    assert basis(b, 0).shape == (8, 16, 0)
    assert basis(b, 1).shape == (8, 16, 3 + 3)  # x, y, z, |x|, |y|, |z|
    assert basis(b, 2).shape == (8, 16, 3 + 5 + 3)  # z^2 is left out: 1 - x^2 - y^2
    phi = basis(b, 2)
    np.testing.assert_allclose(phi[..., -2], np.abs(b[..., 1]), atol=0)  # |y|: the fisheyes' seam kink
    even = basis(b, 4, even=True)  # x^2, y^2, x^4, x^2 y^2, y^4, then |x|, |y|, |z|
    assert even.shape == (8, 16, 5 + 3)
    flipped = b * np.array([-1.0, 1.0, -1.0])  # every even function is the same at (-x, y, -z)
    np.testing.assert_allclose(basis(flipped, 4, even=True), even, atol=1e-12)
    assert not np.allclose(basis(flipped, 2), phi)  # the full basis has odd monomials


def test_fit_recovers_gains_and_field_despite_outliers():
    rng = np.random.default_rng(0)
    b = rng.normal(size=(20000, 3))
    b /= np.linalg.norm(b, axis=1, keepdims=True)
    phi = basis(b, 2)
    beta = rng.normal(scale=0.05, size=phi.shape[1])
    a = np.log([1.3, 1.2, 1.1])
    ratio = a + (phi @ beta)[:, None] + rng.normal(scale=0.005, size=(b.shape[0], 3))
    ratio[::5] += rng.uniform(-1.0, 1.0, size=(ratio[::5].shape[0], 1))  # 20 % parallax-like outliers
    a_fit, beta_fit, info = fit_gain(ratio, phi, PhotometricParams(degree=2))
    field = phi @ beta_fit
    np.testing.assert_allclose(a_fit + field.mean(), a + (phi @ beta).mean(), atol=0.003)
    assert np.abs((field - field.mean()) - (phi @ beta - (phi @ beta).mean())).max() < 0.01
    assert info["sigma"] < 0.01 and 0.7 < info["inliers"] < 0.9


def test_the_block_wise_robust_fit_equals_the_dense_one():
    """``_irls`` sums the normal equations over each camera's columns only: against the same Tukey iterations on
    the whole design (1e-10), two cameras' rows that share a column, their weights tied per pixel."""
    rng = np.random.default_rng(5)
    n, own, shared = 2000, 5, 3  # pixels; each camera's own columns; columns both share
    cols = 2 * own + shared
    design = np.zeros((2, n, 3, cols))
    for i in range(2):
        design[i, :, :, i * own:(i + 1) * own] = rng.normal(size=(n, 3, own))
    design[:, :, :, 2 * own:] = rng.normal(size=(2, n, 3, shared))
    design = design.reshape(-1, cols)
    target = design @ rng.normal(scale=0.1, size=cols) + rng.normal(scale=0.01, size=design.shape[0])
    target[::7] += 0.5  # outliers
    params = PhotometricParams(iterations=5)
    ridge = np.full(cols, 1e-6)
    w = np.ones(target.size)
    coef = np.zeros(cols)
    for _ in range(params.iterations):  # the dense reference
        res = target - design @ coef
        w = tukey_weights(res, params.tukey_c, robust_scale(res, 1e-6, "add"))
        w = np.broadcast_to(w.reshape(2, -1, 3).min(axis=(0, 2))[None, :, None], (2, n, 3)).reshape(-1)
        a = design * w[:, None]
        coef = np.linalg.solve(a.T @ design + np.diag(ridge), a.T @ target)
    got, got_w, _ = _irls(design, target, np.zeros(cols), params, ridge, tied=2)
    np.testing.assert_allclose(got, coef, rtol=0, atol=1e-10)
    np.testing.assert_allclose(got_w, w, rtol=0, atol=1e-10)


def test_one_gain_per_channel_is_corrected_through_a_table():
    """Without a field the same-pixel alignment looks each code up: the per-pixel arithmetic's bytes (the gain is
    read back from the record, so a code at a rounding boundary may differ by one)."""
    rng = np.random.default_rng(6)
    c = rng.integers(10, 230, size=(40, 80, 3), dtype=np.uint8)
    u = linear_to_srgb(srgb_to_linear(c) * np.array([1.3, 1.1, 0.9]))
    out, info = align_images({"C": c, "U": u}, {}, PhotometricParams(iterations=0, pixel_degree=0), others=("U",))
    gain = np.exp(-np.log(np.asarray(info["U"]["gain_rgb"])).astype(np.float32))
    expect = linear_to_srgb(srgb_to_linear(u, np.float32) * gain, np.float32)
    diff = np.abs(out["U"].astype(int) - expect)
    assert diff.max() <= 1 and (diff == 0).mean() > 0.999
    assert np.abs(out["U"].astype(int) - c).max() <= 2


def test_too_few_pixels_give_the_identity():
    a, beta, info = fit_gain(np.zeros((5, 3)), np.zeros((5, 11)), PhotometricParams())
    assert not a.any() and not beta.any() and info["pixels"] == 5


def _relit(frame, gains: dict, edge: dict):
    """The frame with U and R seen through other gains (per channel) and fall-off (along camera Y)."""
    h, w = frame.height, frame.width
    theta = np.arccos(np.clip(np.abs(bearing_grid(w, h)[..., 1]), 0, 1)) / (np.pi / 2)
    images = dict(frame.images)
    for k in ("U", "R"):
        field = (1 - edge[k] * theta ** 2)[..., None] * np.asarray(gains[k])
        images[k] = linear_to_srgb(srgb_to_linear(frame.images[k]) * field)
    return images


@pytest.mark.slow
def test_gains_from_the_same_pixels_and_identity_on_equal_cameras():
    f = make_synthetic_frame(240)
    images = _relit(f, {"U": (1.3, 1.3, 1.3), "R": (0.8, 0.8, 0.8)}, {"U": 0.0, "R": 0.0})
    out, info = align_images(images, f.cameras, PhotometricParams())  # no distance: per-channel gains only
    assert info["U"]["gain_rgb"] == pytest.approx([1.3] * 3, rel=0.05)
    assert info["R"]["gain_rgb"] == pytest.approx([0.8] * 3, rel=0.05)
    # equal cameras: the same-pixel pairs differ by parallax only, which biases the gains by a few per cent (this
    # is why the self-calibration pairs pixels through a distance map, reconstruction.photometry.fit_photometric)
    same, info = align_images(f.images, f.cameras, PhotometricParams())
    for k in ("U", "R"):
        assert info[k]["gain_rgb"] == pytest.approx([1.0] * 3, abs=0.05)


def test_no_calibration_and_the_frame_view():
    f = make_synthetic_frame(120)
    out, info = align_images(f.images, f.cameras, NO_CALIBRATION)
    assert info == {} and all(out[k] is f.images[k] for k in "CUR")
    view = FrameView(f, images=out)
    assert view.width == f.width and view.cameras is f.cameras and view.images is out


@pytest.mark.parametrize("bad", [dict(mode="auto"), dict(degree=7), dict(pixel_degree=-1), dict(factor=0),
                                 dict(dark=0.5, bright=0.4), dict(prepass_factor=0), dict(ridge=-1.0),
                                 dict(hemispheres=-0.1), dict(hemispheres=1.5)])
def test_bad_parameters_are_refused(bad):
    with pytest.raises(ValueError):
        PhotometricParams(**bad)


def test_the_pre_pass_flow_is_a_backend_with_its_parameters_recorded_hashed_and_pickled():
    """A name resolves to the registered backend, the oracle is refused (the pre-pass matches the images), the
    configuration records the backend's parameters, and a method holding it survives pickling (a Dask worker or an
    isolated process gets it) with equal configuration, hash and group key."""
    named = PhotometricParams(prepass_flow="dis")
    assert isinstance(named.prepass_flow, FlowBackend) and named == PhotometricParams()
    assert named.config()["prepass_flow"]["params"] == get_flow("dis").params
    with pytest.raises(ValueError, match="oracle"):
        PhotometricParams(prepass_flow="oracle")
    with pytest.raises(ValueError, match="no-such-flow"):
        PhotometricParams(prepass_flow="no-such-flow")
    other = PhotometricParams(prepass_flow=builtin_flow("dis", {**get_flow("dis").params, "var_iterations": 0}))
    assert other != named and other.config()["prepass_flow"]["params"]["var_iterations"] == 0
    method = fused_mirror()
    back = pickle.loads(pickle.dumps(method))
    assert back.config() == method.config() and back.group_key == method.group_key
    assert hash(back.flow.photometric) == hash(method.flow.photometric)
