"""The sweep cost's per-pixel features (``CostParams.feature``, reconstruction/sweep/cost.py): the default is today's
intensity cost bit for bit, the gain-free features (rank transform, locally normalised intensity) are invariant to
an increasing tone curve applied to one camera within the stated tolerances, and the sweep with either still
reconstructs an exact ray-cast frame."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest

from harness.render.camera import encode
from reconstruction.methods.sweep import SweepMethod
from reconstruction.photometry import srgb_to_linear
from reconstruction.sweep import cost as cost_module
from reconstruction.sweep.cost import (
    FEATURES,
    RANK_RADIUS_PX,
    CostParams,
    _features,
    blur_for_noise,
    build_cost_volume,
    gray_float,
    image_noise,
    local_normalize,
    noise_blur_px,
    rank_transform,
)
from tests.helpers import make_synthetic_frame
from tools.research.select_cost import feature_method

RANK_STEP = 255.0 / ((2 * RANK_RADIUS_PX + 1) ** 2 - 1)
"""One rank of the rank transform, gray levels."""
RESPONSES = ("gamma-1.8", "gamma-2.4", "s-curve-1.6")
"""Response curves other than sRGB (harness.render.camera.encode), as the ``tone`` condition draws them."""


def _features_before(gray_rect, gradient_weight, intensity_weight=1.0):
    """A frozen copy of ``_features`` as it was before ``CostParams.feature`` (the intensity cost)."""
    gu = 0.5 * (np.roll(gray_rect, -1, axis=1) - np.roll(gray_rect, 1, axis=1))
    gv = np.zeros_like(gray_rect)
    gv[1:-1] = 0.5 * (gray_rect[2:] - gray_rect[:-2])
    return np.stack([intensity_weight * gray_rect, gradient_weight * gu, gradient_weight * gv]).astype(np.float32)


@pytest.fixture(scope="module")
def frame():
    return make_synthetic_frame(320)


def _tone(image: np.ndarray, response: str) -> np.ndarray:
    """An ideal sRGB uint8 image as a camera with ``response`` instead of sRGB records it (8 bits)."""
    return encode(srgb_to_linear(image), response)


# ---------------------------------------------------------------------------------------------- the default


def test_the_default_feature_is_the_intensity():
    assert CostParams().feature == "intensity" and FEATURES[0] == "intensity"


@pytest.mark.parametrize("weights", [(2.0, 1.0), (2.0, 0.25)])
def test_default_features_equal_the_frozen_intensity_features(frame, weights):
    """Bit for bit, on a ray-cast gray image and on random gray levels (float32)."""
    rng = np.random.default_rng(0)
    for gray in (gray_float(frame.images["C"], 0.7), rng.uniform(0, 255, (40, 80)).astype(np.float32)):
        np.testing.assert_array_equal(_features(gray, *weights), _features_before(gray, *weights))
        np.testing.assert_array_equal(_features(gray, *weights, "intensity"), _features_before(gray, *weights))


@pytest.mark.parametrize("params", [CostParams(levels=32),
                                    CostParams(levels=32, blur_px=0.7, intensity_weight=0.25, box_px=3)],
                         ids=["sweep", "corrected"])
def test_default_cost_volume_is_unchanged(monkeypatch, params):
    """The default cost volume of a small ray-cast frame equals, bit for bit, the one built with the frozen copy
    of the intensity features (the numba pass and everything around it unchanged)."""
    f = make_synthetic_frame(120)
    got, _ = build_cost_volume(f, params)
    monkeypatch.setattr(cost_module, "_features", lambda g, gw, iw=1.0, feature="intensity":
                        _features_before(g, gw, iw))
    expected, _ = build_cost_volume(f, params)
    np.testing.assert_array_equal(got, expected)


def test_an_unknown_feature_is_refused_in_one_line():
    with pytest.raises(ValueError) as err:
        CostParams(feature="census")
    text = str(err.value)
    assert "\n" not in text and "census" in text and all(name in text for name in FEATURES)


# ------------------------------------------------------------------- the normalised intensity mixed in


@pytest.mark.parametrize("weight", [0.25, 0.5, 1.0])
def test_the_mixed_cost_is_the_weighted_mean_of_both_features_costs(weight):
    """With ``normalized_contrast`` 0 (mixed in at every pixel): each cost is ``(1 - w)`` times the intensity
    volume's plus ``w`` times the normalised intensity's, each truncated on its own, within the two volumes'
    rounding to whole cost units (1 unit)."""
    f = make_synthetic_frame(120)
    mixed, _ = build_cost_volume(f, CostParams(levels=24, normalized_weight=weight, normalized_contrast=0.0))
    alone, _ = build_cost_volume(f, CostParams(levels=24))
    normalized, _ = build_cost_volume(f, CostParams(levels=24, feature="normalized"))
    expected = (1.0 - weight) * alone.astype(np.float64) + weight * normalized
    assert np.abs(mixed - expected).max() <= 1.0
    assert np.abs(normalized.astype(np.float64) - alone).mean() > 10  # the two volumes differ: the test can fail


def test_the_normalised_cost_is_mixed_in_only_where_c_shows_texture():
    """C's pixels whose local contrast is below ``normalized_contrast`` times its noise keep the intensity cost bit for
    bit; the others get the mixed one (on a frame whose upper half is made flat in all three cameras)."""
    f = make_synthetic_frame(120)
    images = {k: im.copy() for k, im in f.images.items()}
    for im in images.values():
        im[: im.shape[0] // 2] = 128
    flat = dataclasses.replace(f, images=images)
    params = CostParams(levels=24, normalized_weight=0.5, normalized_contrast=1.0)
    mixed, _ = build_cost_volume(flat, params)
    alone, _ = build_cost_volume(flat, CostParams(levels=24))
    low = cost_module._low_contrast(*cost_module._contrast_and_noise(images["C"], params), 1.0)
    assert 0.3 < low.mean() < 0.9  # the flat half (and more) is low-contrast, the textured rest is not
    np.testing.assert_array_equal(mixed[low], alone[low])
    assert np.abs(mixed[~low].astype(int) - alone[~low]).mean() > 1


@pytest.mark.parametrize("kwargs", [dict(normalized_weight=-0.1), dict(normalized_weight=1.5),
                                    dict(normalized_contrast=-1.0),
                                    dict(normalized_weight=0.5, feature="normalized")])
def test_a_bad_normalised_mix_is_refused_in_one_line(kwargs):
    with pytest.raises(ValueError) as err:
        CostParams(**kwargs)
    assert "\n" not in str(err.value) and "normalized_" in str(err.value)


def test_the_coarse_room_pass_reads_the_room_without_the_mix():
    """``room_bounds`` of a sweep whose cost mixes in the normalised intensity equals, bit for bit, that of the same
    sweep without the mix (the floor, ceiling, walls and the coarse maps)."""
    from reconstruction.methods.sweep import room_bounds

    f = make_synthetic_frame(120)
    plain = SweepMethod(cost=CostParams(levels=24))
    mixed = dataclasses.replace(plain, cost=dataclasses.replace(plain.cost, normalized_weight=0.5))
    a, b = room_bounds(f, plain, {}), room_bounds(f, mixed, {})
    assert a[:3] == b[:3] and repr(a[3]) == repr(b[3]) and a[5] == b[5]
    for x, y in zip(a[4], b[4], strict=True):
        np.testing.assert_array_equal(x, y)


@pytest.mark.slow
def test_sweep_with_the_normalised_intensity_mixed_in_on_an_exact_frame(frame):
    """The mix keeps the exact ray-cast frame's bound of the normalised feature (measured 1.4 %)."""
    params = CostParams(normalized_weight=0.5)
    assert _relative_mae(frame, SweepMethod(cost=params)) <= BOUNDS["normalized"]


# ------------------------------------------------------------------------------------------- invariance


def test_rank_transform_counts_the_darker_neighbours():
    """A 5 x 5 image of distinct values: a pixel's rank (radius 1) is the count of its 8 neighbours that are
    darker (columns wrap, rows mirror), in units of 255 / 8."""
    g = np.arange(25, dtype=np.float32).reshape(5, 5)[:, [0, 3, 1, 4, 2]]
    got = rank_transform(g, 1) / (255.0 / 8)
    gp = np.pad(g, ((1, 1), (0, 0)), mode="reflect")
    gp = np.concatenate([gp[:, -1:], gp, gp[:, :1]], axis=1)
    expected = sum((gp[1 + dy:6 + dy, 1 + dx:6 + dx] < g).astype(int)
                   for dy in (-1, 0, 1) for dx in (-1, 0, 1))
    np.testing.assert_allclose(got, expected, atol=1e-5)
    flat = rank_transform(np.full((6, 9), 7.0, np.float32))
    assert not flat.any()  # ties are not darker


@pytest.mark.parametrize("gamma", [1.8, 2.4])
def test_rank_is_unchanged_by_a_strictly_increasing_curve(frame, gamma):
    """Without quantisation: exactly equal (only the order of the gray levels counts)."""
    g = gray_float(frame.images["C"], 0.7).astype(np.float64)
    curved = 255.0 * (g / 255.0) ** (2.2 / gamma)
    np.testing.assert_array_equal(rank_transform(curved), rank_transform(g))


@pytest.mark.parametrize("response", RESPONSES)
def test_rank_of_an_8_bit_image_through_another_response_within_one_rank(frame, response):
    """Through another response and 8 bits, ties appear and vanish: at least 85 % of the pixels keep their rank
    within one rank step (measured 89-93 %) and 70 % exactly (measured 72-82 %)."""
    before = rank_transform(gray_float(frame.images["C"], 0.0))
    after = rank_transform(gray_float(_tone(frame.images["C"], response), 0.0))
    steps = np.abs(after - before) / RANK_STEP
    assert np.mean(steps <= 1 + 1e-4) >= 0.85
    assert np.mean(steps <= 1e-4) >= 0.70


def test_local_normalisation_is_unchanged_by_a_gain_and_an_offset():
    """With a negligible ``eps``: within 0.01 gray levels for a gain of 1.7 and an offset of -20 gray levels (on a
    random texture, contrast everywhere; values span about +-50)."""
    g = np.random.default_rng(1).uniform(0, 255, (60, 120)).astype(np.float32)
    a = local_normalize(g, eps=1e-3)
    b = local_normalize(1.7 * g - 20.0, eps=1e-3)
    assert np.abs(a).max() > 30
    np.testing.assert_allclose(b, a, atol=0.01)


@pytest.mark.parametrize("response", RESPONSES)
def test_local_normalisation_of_an_8_bit_image_through_another_response(frame, response):
    """The default normalised intensity moves by a median of at most 1.5 gray levels and a 95th percentile of at
    most 4 (measured 0.25-0.84 and 0.8-2.9), where the intensity itself moves by 6-18 (median)."""
    before = local_normalize(gray_float(frame.images["C"], 0.0))
    after = local_normalize(gray_float(_tone(frame.images["C"], response), 0.0))
    diff = np.abs(after - before)
    assert np.median(diff) <= 1.5 and np.percentile(diff, 95) <= 4.0


# ------------------------------------------------------------------------------------------------ sweep


def _relative_mae(frame, method) -> float:
    out = method.run(frame)
    gt = frame.distance["C"]
    ok = np.isfinite(gt)
    assert out.distance.shape == gt.shape and np.isfinite(out.distance).all()
    return float(np.abs(out.distance[ok] - gt[ok]).mean() / gt[ok].mean())


#: per feature, the bound on the sweep's MAE over the mean distance at 320x160 (measured: intensity 1.4 %, rank
#: 2.8 %, normalized 1.6 %; under the tone mismatch below: intensity 6.1 %, rank 2.9 %, normalized 1.6 %)
BOUNDS = {"rank": 0.04, "normalized": 0.025}


@pytest.mark.slow
@pytest.mark.parametrize("feature", ["rank", "normalized"])
def test_sweep_with_a_gain_free_feature_on_an_exact_frame(frame, feature):
    assert _relative_mae(frame, SweepMethod(cost=CostParams(feature=feature))) <= BOUNDS[feature]


@pytest.mark.slow
@pytest.mark.parametrize("feature", ["rank", "normalized"])
def test_sweep_with_a_gain_free_feature_under_a_response_mismatch(frame, feature):
    """U recorded through gamma 1.8 and R through an S curve of contrast 1.6 (C sRGB): the same bound holds."""
    images = dict(frame.images, U=_tone(frame.images["U"], "gamma-1.8"), R=_tone(frame.images["R"], "s-curve-1.6"))
    toned = dataclasses.replace(frame, images=images)
    assert _relative_mae(toned, SweepMethod(cost=CostParams(feature=feature))) <= BOUNDS[feature]


# ------------------------------------------------------------------------------------------ configurations


def test_a_configuration_from_before_the_feature_reads_as_the_intensity():
    """A results set written before ``CostParams.feature`` existed ran the intensity cost: reusable for the default
    (tools.research.validate_quality), not for a gain-free feature."""
    import json

    from reconstruction.methods.presets import fused_mirror
    from tools.research.validate_quality import config_difference

    old = json.loads(json.dumps(fused_mirror().config()))
    del old["sweep"]["cost"]["feature"], old["sweep"]["corrected_cost"]["feature"]
    assert config_difference(old, fused_mirror().config()) is None
    assert config_difference(old, feature_method("rank").config()).endswith("'intensity' vs 'rank'")


@pytest.mark.parametrize("feature", FEATURES)
def test_the_measured_variants_use_the_feature_in_both_costs(feature):
    """tools.research.select_cost: ``fused-mirror`` with ``feature`` in its sweep's cost and corrected cost, every
    other parameter the default's."""
    from reconstruction.methods.presets import fused_mirror

    base, method = fused_mirror(), feature_method(feature)
    assert method.sweep.cost == dataclasses.replace(base.sweep.cost, feature=feature)
    assert method.sweep.corrected_cost == dataclasses.replace(base.sweep.corrected_cost, feature=feature)
    assert method.label == ("fused-mirror" if feature == "intensity" else f"fused-mirror-{feature}")
    assert dataclasses.replace(method, sweep=base.sweep, label=base.label).config() == base.config()


def test_image_noise_reads_the_noise_not_the_shading():
    """Immerkaer's estimate on a smoothly shaded 8-bit image: below 0.3 gray levels without noise; with independent
    Gaussian noise of 3 and 6 gray levels per channel, within 15 % of the noise of the channels' mean (3 / sqrt 3
    and 6 / sqrt 3)."""
    y, x = np.mgrid[0:250, 0:500]
    img = np.repeat((120 + 100 * np.sin(x / 40.0) * np.cos(y / 30.0))[..., None], 3, axis=-1)
    assert image_noise(img.astype(np.uint8)) < 0.3
    rng = np.random.default_rng(3)
    for sigma in (3.0, 6.0):
        noisy = np.clip(img + rng.normal(scale=sigma, size=img.shape), 0, 255).astype(np.uint8)
        assert image_noise(noisy) == pytest.approx(sigma / np.sqrt(3.0), rel=0.15)


def test_image_noise_at_a_coarser_scale_reads_white_noise_the_same_and_sees_what_jpeg_flattened():
    """At scale 2 (the image's 2 x 2 means, times 2) white noise reads as at the pixel scale (within 15 %); after
    JPEG coding at quality 70, 6 gray levels per channel read below a quarter of their channel-mean figure at the
    pixel scale (the coding flattens the finest frequencies) and within 25 % of it at scale 2."""
    y, x = np.mgrid[0:250, 0:500]
    img = np.repeat((120 + 100 * np.sin(x / 40.0) * np.cos(y / 30.0))[..., None], 3, axis=-1)
    rng = np.random.default_rng(5)
    sigma = 6.0
    noisy = np.clip(img + rng.normal(scale=sigma, size=img.shape), 0, 255).astype(np.uint8)
    assert image_noise(noisy, 2) == pytest.approx(sigma / np.sqrt(3.0), rel=0.15)
    ok, buf = cv2.imencode(".jpg", noisy, [cv2.IMWRITE_JPEG_QUALITY, 70])
    coded = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED)
    assert ok and image_noise(coded) < 0.25 * sigma / np.sqrt(3.0)
    assert image_noise(coded, 2) == pytest.approx(sigma / np.sqrt(3.0), rel=0.25)
    with pytest.raises(ValueError, match="noise_scale"):
        CostParams(noise_scale=0)


def test_noise_blur_grows_with_the_noise_above_its_floor_only():
    params = CostParams(blur_px=0.7, noise_blur=1.0, noise_floor=1.0)
    assert noise_blur_px(params, 0.5) == 0.7 and noise_blur_px(params, 1.5) == 0.7  # never below the cost's blur
    assert noise_blur_px(params, 2.2) == pytest.approx(1.2, abs=1e-12)
    assert noise_blur_px(params, 9.0) == params.max_noise_blur_px == 1.5  # at most that
    assert noise_blur_px(dataclasses.replace(params, max_noise_blur_px=2.0), 9.0) == 2.0
    assert noise_blur_px(CostParams(blur_px=0.7), 9.0) == 0.7  # noise_blur 0: off
    # the ramp itself: 0 at and below the floor or when off, linear above it, capped
    assert blur_for_noise(1.0, 2.0, 1.0, 3.0) == 0.0 and blur_for_noise(5.0, 0.0, 1.0, 3.0) == 0.0
    assert blur_for_noise(1.5, 2.0, 1.0, 3.0) == pytest.approx(1.0, abs=1e-12)
    assert blur_for_noise(4.0, 2.0, 1.0, 3.0) == 3.0
    with pytest.raises(ValueError, match="noise_blur"):
        CostParams(noise_blur=-1.0)
