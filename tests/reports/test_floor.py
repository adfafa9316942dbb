"""reports.floor: the distance error of an ideal matcher (angular error px per pair, pairs combined by inverse
variance) and the floor MAE, against hand-computed values, the law of sines and a simulated matcher."""

from __future__ import annotations

import math

import numpy as np
import pytest

from reconstruction.camera.equirect import bearing_grid
from reconstruction.camera.rig import Rig
from reports.floor import (
    FLOOR_PX,
    FLOOR_PX_CHOICES,
    GAUSSIAN_MAE_FACTOR,
    floor_fields,
    floor_mae,
    floor_sigma,
    frame_floor_sigma,
    pair_sigma,
    pixel_pitch_rad,
    region_floors,
    times_floor,
)
from reports.metrics import summary

B = 0.4  # baseline, metres
T_U, T_R = np.array([0.0, 0.0, B]), np.array([B, 0.0, 0.0])  # the default rig's baselines, world (identity rotation)


def _lonlat(h: int):
    """(H, W) longitude and latitude of the pixel centres, radians, by the equirect convention (not the library)."""
    w = 2 * h
    v, u = np.mgrid[0:h, 0:w]
    return 2 * np.pi * (u + 0.5) / w - np.pi, np.pi / 2 - np.pi * (v + 0.5) / h


def _sphere_sigma(h: int, r: float, px: float):
    """Hand formulas for a sphere of radius r around C (d = r everywhere), default rig, identity rotation:
    cos(alpha_U) = sin(phi), cos(alpha_R) = cos(phi) sin(lam) and
    sigma_k = delta (r^2 - 2 r B cos(alpha_k) + B^2) / (B sin(alpha_k)); metres."""
    lam, phi = _lonlat(h)
    delta = px * math.pi / h
    cos_u = np.sin(phi)
    cos_r = np.cos(phi) * np.sin(lam)
    s_u = delta * (r * r - 2 * r * B * cos_u + B * B) / (B * np.sqrt(1 - cos_u ** 2))
    s_r = delta * (r * r - 2 * r * B * cos_r + B * B) / (B * np.sqrt(1 - cos_r ** 2))
    return s_u, s_r, (s_u ** -2 + s_r ** -2) ** -0.5


def test_pair_sigma_hand_computed():
    """a perpendicular to t, d = 2 m, B = 0.4 m, delta = 0.01 rad: |d a - t|^2 = 4.16 m^2, |a x t| = 0.4 m, so
    sigma = 0.01 * 4.16 / 0.4 = 0.104 m (the approximation d^2 delta / (B sin alpha) would give 0.100 m)."""
    got = pair_sigma(np.array([0.0, 1.0, 0.0]), np.array(2.0), T_R, 0.01)
    assert got == pytest.approx(0.104, abs=1e-12)  # metres
    # 60 degrees from the baseline, d = 1 m: r_K^2 = 1 - 2 * 0.4 * 0.5 + 0.16 = 0.76, B sin(alpha) = 0.4 * sqrt(3)/2
    a = np.array([0.5, math.sqrt(3) / 2, 0.0])
    assert pair_sigma(a, np.array(1.0), T_R, 0.01) == pytest.approx(0.01 * 0.76 / (0.2 * math.sqrt(3)), abs=1e-12)


@pytest.mark.parametrize("alpha_deg", [5.0, 30.0, 90.0, 150.0, 175.0])
@pytest.mark.parametrize("d", [0.6, 2.0, 8.0])
def test_pair_sigma_is_the_law_of_sines_derivative(alpha_deg, d):
    """sigma / delta = dd/dbeta, beta the angle at K: checked by a central difference of the law of sines
    d(beta) = B sin(beta) / sin(beta - alpha), beta(d) = atan2(d sin(alpha), d cos(alpha) - B)."""
    alpha = math.radians(alpha_deg)
    beta = math.atan2(d * math.sin(alpha), d * math.cos(alpha) - B)
    eps = 1e-6
    d_of = lambda b: B * math.sin(b) / math.sin(b - alpha)  # noqa: E731
    numeric = (d_of(beta + eps) - d_of(beta - eps)) / (2 * eps)  # metres per radian
    a = np.array([math.cos(alpha), math.sin(alpha), 0.0])
    assert pair_sigma(a, np.array(d), T_R, 1.0) == pytest.approx(abs(numeric), rel=1e-6)


def test_epipoles_get_an_infinite_pair_sigma_and_leave_the_other_pair():
    assert pair_sigma(np.array([1.0, 0.0, 0.0]), np.array(2.0), T_R, 0.01) == math.inf  # towards R
    assert pair_sigma(np.array([-1.0, 0.0, 0.0]), np.array(2.0), T_R, 0.01) == math.inf  # away from R
    h = 20
    gt = np.full((h, 2 * h), 3.0)
    a = bearing_grid(2 * h, h)
    t_on = 2.0 * a[7, 11]  # a baseline exactly along pixel (7, 11)'s bearing: that pixel is on its epipole
    alone = floor_sigma(gt, np.eye(3), [t_on])
    assert alone[7, 11] == math.inf and np.isfinite(np.delete(alone.ravel(), 7 * 2 * h + 11)).all()
    both = floor_sigma(gt, np.eye(3), [t_on, T_U])
    only_u = floor_sigma(gt, np.eye(3), [T_U])
    assert both[7, 11] == pytest.approx(only_u[7, 11], rel=1e-15)  # the epipole's pair carries no weight
    assert np.all(both <= only_u * (1 + 1e-12))  # a second pair never makes it worse


@pytest.mark.parametrize("r", [1.0, 3.5])
def test_sphere_around_the_rig_is_analytic(r):
    """d = r everywhere: every pixel's combined sigma equals the hand formula, and the floor is sqrt(2/pi) times
    their mean over all pixels."""
    h = 40
    s_u, s_r, s = _sphere_sigma(h, r, FLOOR_PX)
    got = floor_sigma(np.full((h, 2 * h), r), np.eye(3), [T_U, T_R])
    np.testing.assert_allclose(got, s, rtol=1e-12, atol=0)  # metres
    assert floor_mae(got) == pytest.approx(math.sqrt(2 / math.pi) * s.mean(), rel=1e-12)
    # looking straight ahead on the equator both pairs see the point at 90 degrees: sigma_U = sigma_R =
    # delta (r^2 + B^2) / B, combined / sqrt(2); the nearest pixels are half a pixel off, within 0.1 %
    ahead = FLOOR_PX * math.pi / h * (r * r + B * B) / B / math.sqrt(2)
    assert got[h // 2, h] == pytest.approx(ahead, rel=1e-3)
    assert s_u.shape == s_r.shape == (h, 2 * h)


def test_default_rig_frame_is_the_same_as_the_arrays():
    h = 16
    gt = np.full((h, 2 * h), 2.0)

    class FrameLike:  # what frame_floor_sigma reads of a frame
        scene, viewpoint = "sphere", "v0"
        distance = {"C": gt}
        cameras = Rig(baseline_m=B).poses()

    _, _, s = _sphere_sigma(h, 2.0, FLOOR_PX)
    np.testing.assert_allclose(frame_floor_sigma(FrameLike()), s, rtol=1e-12, atol=0)


@pytest.mark.parametrize("px", [*FLOOR_PX_CHOICES, 2.0])
def test_linear_in_px(px):
    rng = np.random.default_rng(0)
    gt = rng.uniform(0.5, 9.0, (12, 24))
    base = floor_sigma(gt, np.eye(3), [T_U, T_R], 0.25)
    np.testing.assert_allclose(floor_sigma(gt, np.eye(3), [T_U, T_R], px), base * (px / 0.25), rtol=1e-12, atol=0)
    assert floor_mae(floor_sigma(gt, np.eye(3), [T_U, T_R], px)) == pytest.approx(floor_mae(base) * px / 0.25,
                                                                                   rel=1e-12)
    assert pixel_pitch_rad(500) == pytest.approx(math.pi / 500, abs=1e-15)  # radians per pixel


def test_only_scored_pixels_count_and_regions_use_the_same_pixels():
    h = 8
    gt = np.full((h, 2 * h), 2.0)
    gt[0, :4] = np.inf
    gt[1, 0] = np.nan
    gt[1, 1] = 0.0
    gt[2, 2] = -1.0
    s = floor_sigma(gt, np.eye(3), [T_U, T_R])
    scored = np.isfinite(gt) & (gt > 0)
    assert np.isnan(s[~scored]).all() and np.isfinite(s[scored]).all()
    assert floor_mae(s) == pytest.approx(GAUSSIAN_MAE_FACTOR * s[scored].mean(), rel=1e-12)
    top = np.zeros(gt.shape, dtype=bool)
    top[:2] = True  # holds 6 unscored pixels: they are left out, as summary leaves them out
    assert floor_mae(s, top) == pytest.approx(GAUSSIAN_MAE_FACTOR * s[top & scored].mean(), rel=1e-12)
    assert summary(gt + 0.1, gt, mask=top)["valid_px"] == int((top & scored).sum()) == 2 * 2 * h - 6
    floors = region_floors(s, {"all": scored, "top": top, "none": np.zeros(gt.shape, dtype=bool)})
    assert floors["all"] == floor_mae(s) and floors["top"] == floor_mae(s, top) and math.isnan(floors["none"])


def test_a_simulated_ideal_matcher_has_the_floor_as_its_mae():
    """Gaussian angular errors of std delta on the angle at K of each pair, exact law-of-sines triangulation, pairs
    combined with inverse-variance weights: the MAE over the pixels away from the epipoles (15 degrees) is the
    floor over the same pixels within 1.5 % (first-order theory; seeded)."""
    h, r = 200, 2.0
    gt = np.full((h, 2 * h), r)
    a = bearing_grid(2 * h, h)
    delta = FLOOR_PX * math.pi / h
    sigma = floor_sigma(gt, np.eye(3), [T_U, T_R])
    rng = np.random.default_rng(7)
    num = den = 0.0
    keep = np.ones(gt.shape, dtype=bool)
    for t in (T_U, T_R):
        cos_a = a @ t / B
        alpha = np.arccos(np.clip(cos_a, -1, 1))
        keep &= np.abs(cos_a) < math.cos(math.radians(15.0))
        beta = np.arctan2(r * np.sin(alpha), r * np.cos(alpha) - B) + delta * rng.standard_normal(gt.shape)
        with np.errstate(divide="ignore", invalid="ignore"):
            d_k = B * np.sin(beta) / np.sin(beta - alpha)
        w = pair_sigma(a, gt, t, delta) ** -2
        num, den = num + w * d_k, den + w
    pred = num / den
    mae = summary(pred, gt, mask=keep)["mae_m"]
    assert keep.sum() > 0.5 * keep.size
    assert mae == pytest.approx(floor_mae(sigma, keep), rel=0.015)  # metres (measured: 0.9997 x the floor)
    # the mean sigma alone (an error of exactly sigma at every pixel) is 25 % above what the matcher makes
    assert mae < 0.9 * np.mean(sigma[keep])


def test_times_floor_and_the_row_fields():
    assert times_floor(0.2, 0.05) == pytest.approx(4.0, abs=1e-12)
    assert math.isnan(times_floor(0.2, float("nan"))) and math.isnan(times_floor(0.2, 0.0))
    assert math.isnan(times_floor(float("nan"), 0.1)) and math.isnan(times_floor(0.2, math.inf))
    np.testing.assert_allclose(times_floor(np.array([0.1, 0.3]), np.array([0.1, np.nan])), [1.0, np.nan])
    assert floor_fields(0.3, 0.1) == {"floor_m": 0.1, "mae_x_floor": pytest.approx(3.0, abs=1e-12)}


@pytest.mark.parametrize(("call", "message"), [
    (lambda: floor_sigma(np.ones((4, 6)), np.eye(3), [T_U]), "equirect"),
    (lambda: floor_sigma(np.ones((4, 8)), np.eye(3), [T_U], px=0.0), "px must be finite and positive"),
    (lambda: floor_sigma(np.ones((4, 8)), np.eye(3), []), "at least one baseline"),
    (lambda: floor_sigma(np.ones((4, 8)), np.eye(3), [np.zeros(3)]), "non-zero"),
    (lambda: floor_mae(np.ones((4, 8)), np.ones((4, 8))), "bool array"),
])
def test_bad_input_is_refused(call, message):
    with pytest.raises(ValueError, match=message):
        call()
