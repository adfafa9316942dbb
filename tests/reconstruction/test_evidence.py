"""The test that decides whether a self-calibration's correction is applied (reconstruction.evidence), and the
photometric fit that uses it (reconstruction.photometry.fit_photometric): cameras that agree get nothing, cameras
that differ get their difference, on exact ray-cast frames."""

from __future__ import annotations

import numpy as np
import pytest

from reconstruction.camera.equirect import bearing_grid
from reconstruction.evidence import (
    BLOCKS,
    hemisphere_rows,
    hotelling,
    jackknife_hemispheres,
    jackknife_linear,
    sphere_blocks,
)
from reconstruction.photometry import (
    PhotometricParams,
    apply_photometric,
    basis,
    fit_photometric,
    linear_to_srgb,
    srgb_to_linear,
)
from tests.helpers import make_synthetic_frame


def _unit(rng, n):
    b = rng.normal(size=(n, 3))
    return b / np.linalg.norm(b, axis=1, keepdims=True)


def test_blocks_cover_the_sphere():
    blocks = sphere_blocks(bearing_grid(64, 32))
    assert blocks.shape == (32, 64) and set(np.unique(blocks)) == set(range(BLOCKS))
    assert (blocks[:16] % 2 == 0).all() and (blocks[16:] % 2 == 1).all()  # above / below the horizon


def test_jackknife_of_a_constant_offset_rejects_only_a_real_one():
    """A mean of noisy samples: zero mean is not rejected (p > 0.01), a mean of 4 noise standard errors is
    (p < 1e-3); the full-data solution is the weighted mean (1e-9)."""
    rng = np.random.default_rng(1)
    b = _unit(rng, 20000)
    blocks = sphere_blocks(b)
    design = np.ones((b.shape[0], 1))
    noise = rng.normal(scale=1.0, size=b.shape[0])
    theta, cov, used = jackknife_linear(design, noise, np.ones(b.shape[0]), blocks)
    assert used == BLOCKS and abs(theta[0] - noise.mean()) < 1e-9  # the ridge: 1e-9 of the trace
    assert hotelling(theta, cov, used)["p_value"] > 0.01
    shift = 4.0 / np.sqrt(b.shape[0])
    theta, cov, used = jackknife_linear(design, noise + shift + 0.05, np.ones(b.shape[0]), blocks)
    assert hotelling(theta, cov, used)["supported"]


def test_jackknife_equals_refitting_without_each_block():
    """Against the definition: the weighted fit without each block's rows solved anew (1e-10), blocks given in any
    order; a block with fewer than ``min_samples`` weighted rows stays in every fit."""
    rng = np.random.default_rng(3)
    n, p = 3000, 4
    design = rng.normal(size=(n, p))
    target = design @ rng.normal(size=p) + rng.normal(scale=0.1, size=n)
    weights = rng.uniform(0.0, 1.0, n) * (rng.uniform(size=n) > 0.1)
    blocks = rng.integers(0, 9, n)
    blocks[rng.choice(n, 5, replace=False)] = 9  # a block too small to leave out
    ridge = np.full(p, 1e-6)

    def solve(rows):
        a = design[rows] * weights[rows, None]
        return np.linalg.solve(a.T @ design[rows] + np.diag(ridge), a.T @ target[rows])

    theta, cov, used = jackknife_linear(design, target, weights, blocks, ridge, min_samples=50)
    np.testing.assert_allclose(theta, solve(np.arange(n)), rtol=0, atol=1e-10)
    est = np.stack([solve(blocks != b) for b in range(9)])
    dev = est - est.mean(axis=0)
    assert used == 9
    np.testing.assert_allclose(cov, 8 / 9 * dev.T @ dev, rtol=1e-8, atol=1e-14)


def test_a_block_effect_is_not_a_camera_effect():
    """An offset that only one block of the sphere shows (a scene's, not a camera's) is not supported, though it
    moves the full-data mean by many standard errors."""
    rng = np.random.default_rng(2)
    b = _unit(rng, 20000)
    blocks = sphere_blocks(b)
    y = rng.normal(scale=0.01, size=b.shape[0]) + np.where(blocks == 5, 0.5, 0.0)
    theta, cov, used = jackknife_linear(np.ones((b.shape[0], 1)), y, np.ones(b.shape[0]), blocks)
    assert theta[0] > 0.01 and not hotelling(theta, cov, used)["supported"]


def test_each_hemisphere_alone_is_the_jackknife_of_its_rows():
    """:func:`jackknife_hemispheres` is :func:`jackknife_linear` of the rows above the horizon and of those below
    (1e-12); a hemisphere without rows carries no evidence."""
    rng = np.random.default_rng(4)
    b = _unit(rng, 6000)
    blocks = sphere_blocks(b)
    design = np.column_stack([np.ones(b.shape[0]), b[:, 0] ** 2])
    target = design @ np.array([0.1, -0.2]) + rng.normal(scale=0.05, size=b.shape[0])
    weights = rng.uniform(0.5, 1.0, b.shape[0])
    up, down = hemisphere_rows(blocks)
    assert up.sum() + down.sum() == b.shape[0] and np.array_equal(up, b[:, 2] >= 0)
    for (theta, cov, used), rows in zip(jackknife_hemispheres(design, target, weights, blocks), (up, down),
                                        strict=True):
        ref = jackknife_linear(design[rows], target[rows], weights[rows], blocks[rows])
        np.testing.assert_allclose(theta, ref[0], rtol=0, atol=1e-12)
        np.testing.assert_allclose(cov, ref[1], rtol=1e-10, atol=1e-15)
        assert used == ref[2] == BLOCKS // 2
    theta, cov, used = jackknife_hemispheres(design[up], target[up], weights[up], blocks[up])[1]
    assert used == 0 and not hotelling(theta, cov, used)["supported"]


def test_an_offset_in_every_block_below_the_horizon_is_not_seen_from_above():
    """A polished floor's reflection: an offset of 0.1 in every block below the horizon passes the whole sphere's
    jackknife test (every block is alike within its hemisphere), but the fit of the rows above the horizon alone
    finds under a tenth of it."""
    rng = np.random.default_rng(5)
    b = _unit(rng, 20000)
    blocks = sphere_blocks(b)
    design, weights = np.ones((b.shape[0], 1)), np.ones(b.shape[0])
    y = rng.normal(scale=0.01, size=b.shape[0]) + np.where(b[:, 2] < 0, 0.1, 0.0)
    theta, cov, used = jackknife_linear(design, y, weights, blocks)
    assert hotelling(theta, cov, used)["supported"] and theta[0] > 0.04
    (above, _, _), (below, _, _) = jackknife_hemispheres(design, y, weights, blocks)
    assert abs(above[0]) < 0.01 and below[0] > 0.09


def test_hotelling_needs_more_blocks_than_quantities():
    ev = hotelling(np.ones(3), np.eye(3), 3)
    assert not ev["supported"] and ev["p_value"] == 1.0


def _relit(frame, cams: dict):
    """The frame's images with per-camera gains (per channel) and a lens-axis fall-off along camera Y."""
    h, w = frame.height, frame.width
    theta = np.arccos(np.clip(np.abs(bearing_grid(w, h)[..., 1]), 0, 1)) / (np.pi / 2)
    images = dict(frame.images)
    for k, (gains, edge) in cams.items():
        field = (1 - edge * theta ** 2)[..., None] * np.asarray(gains)
        images[k] = linear_to_srgb(srgb_to_linear(frame.images[k]) * field)
    return images


@pytest.mark.slow
def test_cameras_that_agree_get_no_correction():
    frame = make_synthetic_frame(width=480)
    model, record = fit_photometric(frame.images, frame.cameras, frame.distance["C"], PhotometricParams())
    assert model.is_identity and not record["applied"]
    assert apply_photometric(frame.images, model)["U"] is frame.images["U"]


@pytest.mark.slow
@pytest.mark.parametrize("share", [0.0, 0.5, 1.0])
def test_cameras_that_differ_are_corrected_to_c(share):
    """U and R with other gains (0.8-1.2) and fall-off (20 %, 30 %): both are applied, also when each must be at
    least its floor (or half of it) as fitted from each hemisphere alone (``hemispheres``), and the corrected
    images are within 1 grey level of the originals on 95 % of the pixels."""
    frame = make_synthetic_frame(width=480)
    images = _relit(frame, {"U": ((1.2, 1.1, 0.9), 0.2), "R": ((0.8, 0.85, 0.9), 0.3)})
    model, record = fit_photometric(images, frame.cameras, frame.distance["C"], PhotometricParams(hemispheres=share))
    for k in ("U", "R"):
        assert record[k]["gain"]["applied"] and record[k]["field"]["applied"]
        assert ("hemispheres" in record[k]["field"]) == (share > 0)
    out = apply_photometric(images, model)
    assert out["C"] is images["C"]
    for k in ("U", "R"):
        diff = np.abs(out[k].astype(int) - frame.images[k].astype(int))
        assert np.percentile(diff, 95) <= 1.0


@pytest.mark.slow
def test_a_brighter_lower_hemisphere_is_not_a_camera_gain_from_both_hemispheres():
    """U sees everything below the horizon 25 % brighter (a polished floor's view-dependent reflection seen from U
    only): the whole sphere's fit applies a gain to U; with ``hemispheres`` 1 nothing is applied, since the pixels
    above the horizon alone find a gain below the floor (0.05), those below one four times it."""
    frame = make_synthetic_frame(width=480)
    h = frame.height
    images = dict(frame.images)
    lower = (np.arange(h) >= h // 2)[:, None, None]
    images["U"] = linear_to_srgb(srgb_to_linear(frame.images["U"]) * np.where(lower, 1.25, 1.0))
    _, record = fit_photometric(images, frame.cameras, frame.distance["C"], PhotometricParams())
    assert record["U"]["gain"]["applied"] and "hemispheres" not in record["U"]["gain"]
    model, record = fit_photometric(images, frame.cameras, frame.distance["C"], PhotometricParams(hemispheres=1.0))
    above, below = record["U"]["gain"]["hemispheres"]
    assert model.is_identity and above["size"] < 0.05 and below["size"] > 0.2


@pytest.mark.slow
def test_a_camera_with_another_response_curve_is_corrected_to_c():
    """U encodes its linear light with gamma 1.8 and R with gamma 2.6 instead of sRGB, after a gain: each
    response is applied (its slope in K's own log level within 0.05 of ``1 - G / 2.2``, 2.2 about sRGB's
    effective gamma), and the corrected images are within 3 grey levels of the originals on 90 % of the
    pixels; without the response term they are not (a gain alone cannot follow a power law)."""
    frame = make_synthetic_frame(width=480)
    images = dict(frame.images)
    gammas = {"U": 1.8, "R": 2.6}
    for k, g in gammas.items():
        encoded = (np.clip(srgb_to_linear(frame.images[k]) * 1.1, 0, 1) ** (1 / g) * 255 + 0.5).astype(np.uint8)
        images[k] = encoded
    model, record = fit_photometric(images, frame.cameras, frame.distance["C"], PhotometricParams())
    gain_only, _ = fit_photometric(images, frame.cameras, frame.distance["C"], PhotometricParams(response=0))
    out, out_gain = apply_photometric(images, model), apply_photometric(images, gain_only)
    for k, g in gammas.items():
        assert record[k]["response"]["applied"]
        assert abs(model.responses[k][0] - (1 - g / 2.2)) < 0.05
        diff = np.abs(out[k].astype(int) - frame.images[k].astype(int))
        assert np.percentile(diff, 90) <= 3.0
        assert np.percentile(np.abs(out_gain[k].astype(int) - frame.images[k].astype(int)), 90) > 3.0


@pytest.mark.slow
def test_a_fall_off_all_three_share_is_removed_from_the_parallax():
    """The same 50 % fall-off in C, U and R (the common_field fit): applied, and the log ratio of the corrected to
    the original images spans a tenth of what it spanned (5th-95th percentile)."""
    frame = make_synthetic_frame(width=480)
    images = _relit(frame, {k: ((1.0, 1.0, 1.0), 0.5) for k in ("C", "U", "R")})
    model, record = fit_photometric(images, frame.cameras, frame.distance["C"], PhotometricParams(common_field=True))
    assert record["common"]["field"]["applied"] and model.common is not None
    out = apply_photometric(images, model)
    ok = (frame.images["C"].mean(-1) > 20) & (frame.images["C"].mean(-1) < 230)

    def spread(img):
        r = np.log(srgb_to_linear(img).mean(-1) + 1e-4) - np.log(srgb_to_linear(frame.images["C"]).mean(-1) + 1e-4)
        lo, hi = np.percentile(r[ok], [5, 95])
        return hi - lo

    assert spread(out["C"]) < 0.1 * spread(images["C"])


def test_the_central_basis_is_the_same_at_opposite_bearings():
    """A fall-off of two like back-to-back lenses is the same at b and -b whatever their axis: the central basis
    keeps exactly the monomials of even total degree (x^2, xy, xz, y^2, yz at degree 2) and |x|, |y|, |z|."""
    b = bearing_grid(16, 8)
    phi = basis(b, 2, central=True)
    assert phi.shape == (8, 16, 5 + 3)
    np.testing.assert_allclose(basis(-b, 2, central=True), phi, atol=1e-12)
    assert not np.allclose(basis(-b, 2), basis(b, 2))  # the full basis has odd monomials
