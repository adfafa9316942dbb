"""Ground-truth-free quality measures on an exact ray-cast frame."""

from __future__ import annotations

import numpy as np
import pytest

from harness.commands.perturb import perturb_frame
from reconstruction import quality as Q
from reconstruction.camera.equirect import bearing_grid
from tests.helpers import make_synthetic_frame


@pytest.fixture(scope="module")
def frame():
    return make_synthetic_frame(width=160)


def test_residual_small_at_true_distance_and_grows_with_error(frame):
    gt = frame.distance["C"]
    med = [float(np.nanmedian(Q.photometric_residual(frame, gt * s))) for s in (1.0, 1.05, 1.2)]
    assert med[0] < 3.0  # grey levels (0..255): interpolation of the anti-aliased renders, no more
    assert med[0] < med[1] < med[2]
    assert med[2] > 1.5 * med[0]


def test_distance_residual_ranks_pixels_with_error(frame):
    gt = frame.distance["C"]
    rng = np.random.default_rng(0)
    scale = np.where(rng.random(gt.shape) < 0.5, 1.0, 1.15)  # half the pixels 15 % off
    scale = np.kron(scale[::8, ::8], np.ones((8, 8)))[: gt.shape[0], : gt.shape[1]]  # in 8x8 blocks
    e = Q.distance_residual(frame, gt * scale)
    ok = np.isfinite(e)
    assert ok.mean() > 0.95
    assert np.median(e[ok & (scale > 1)]) > 1.5 * np.median(e[ok & (scale == 1)])


def test_pair_agreement_small_at_true_distance(frame):
    a = Q.pair_agreement(frame, frame.distance["C"])
    full = np.log(1 + max(Q.SEARCH_STEPS)) - np.log(1 + min(Q.SEARCH_STEPS))  # the largest disagreement possible
    assert np.nanmedian(a) < 0.25 * full
    assert np.nanmax(a) <= full + 1e-6


def test_invalid_distance_gives_nan(frame):
    d = frame.distance["C"].copy()
    d[:10] = np.nan
    maps, _ = Q.assess(frame, d)
    for m in maps.values():
        assert np.isnan(m[:10]).all() and np.isfinite(m[20:-20]).mean() > 0.9


def test_calibration_check_flags_half_degree_rotation(frame):
    exact = Q.calibration_score(frame, frame.distance["C"])["score"]
    told = perturb_frame(frame, [("rotation", 0.5)], seed=3, source={"path": "-", "sha256": "-"})
    off = Q.calibration_score(told, frame.distance["C"])["score"]
    assert exact <= Q.CALIBRATION_THRESHOLD < off
    # with the true distance the valley offsets estimate the error itself: measured 0.04 deg exact and 0.5-0.6 deg
    # for 0.5 deg (seeds 1-3) on this 160x80 frame
    assert exact < 0.1 and 0.35 < off < 1.0


def test_geometric_uncertainty_is_d_squared_over_the_perpendicular_baselines(frame):
    d = np.full((frame.height, frame.width), 2.0)
    g = Q.geometric_uncertainty(frame, d)
    assert np.isfinite(g).all()
    # C-U vertical (0.4 m), C-R horizontal (0.4 m): on the horizon looking perpendicular to C-R (the bearing of
    # the column where the bearing is orthogonal to both baselines) sum (|b| sin g)^2 = 2 * 0.16
    b = bearing_grid(frame.width, frame.height, rotation=frame.cameras["C"].rotation)
    c = frame.cameras["C"].position
    ortho = np.ones(b.shape[:2], bool)
    for k in ("U", "R"):
        base = np.asarray(frame.cameras[k].position) - c
        ortho &= np.abs(b @ (base / np.linalg.norm(base))) < 0.02
    assert ortho.any()
    lengths = [np.linalg.norm(np.asarray(frame.cameras[k].position) - c) for k in ("U", "R")]
    expect = 4.0 / np.sqrt(sum(x ** 2 for x in lengths))
    np.testing.assert_allclose(g[ortho], expect, rtol=1e-3)
    # it grows with the square of the distance and is NaN where the distance is invalid
    np.testing.assert_allclose(Q.geometric_uncertainty(frame, 2 * d), 4 * g, rtol=1e-5)
    d[0, 0] = np.nan
    assert np.isnan(Q.geometric_uncertainty(frame, d)[0, 0])


def test_disagreement_is_the_smoothed_log_ratio_and_wraps():
    d = np.full((40, 80), 3.0)
    ref = d.copy()
    np.testing.assert_allclose(Q.disagreement(d, ref), 0.0, atol=1e-7)
    ref[:, :10] = 6.0  # a factor 2 off at the seam's right side
    x = Q.disagreement(d, ref, sigma_px=1.0)
    assert x[20, 5] == pytest.approx(np.log(2.0), abs=1e-4)  # inside the band
    assert x[20, 40] == pytest.approx(0.0, abs=1e-6)
    assert x[20, 79] > 0.05  # smoothed across the seam from column 0
    ref[5, 40] = np.nan  # no reference: a factor e apart
    assert Q.disagreement(d, ref, sigma_px=0)[5, 40] == pytest.approx(1.0)
    d[7, 7] = -1.0
    assert np.isnan(Q.disagreement(d, ref)[7, 7])


def test_uncertainty_is_the_product_of_the_factors_the_prediction_has(frame):
    gt = frame.distance["C"]
    conf = np.full(gt.shape, 0.75, np.float32)
    maps, _ = Q.assess(frame, gt, conf, reference=gt * 1.1)
    f = Q.uncertainty_factors(maps, conf)
    assert set(f) == set(Q.FACTORS)
    np.testing.assert_allclose(f["ambiguity"], 0.25)
    np.testing.assert_allclose(f["disagreement"][40:-40, 40:-40], np.log(1.1) + Q.DISAGREEMENT_FLOOR, rtol=1e-4)
    expect = np.prod([f[n] for n in Q.UNCERTAINTY_FACTORS], axis=0)
    np.testing.assert_allclose(maps["uncertainty"], expect, rtol=1e-6)
    plain, _ = Q.assess(frame, gt)  # no confidence, no reference: those factors count as 1
    assert "disagreement" not in plain and set(Q.uncertainty_factors(plain)) == {"geometric", "residual"}
    np.testing.assert_allclose(plain["uncertainty"], Q.combine(Q.uncertainty_factors(plain), Q.UNCERTAINTY_FACTORS),
                               rtol=1e-6)
    with pytest.raises(ValueError, match="none of the factors"):
        Q.combine({"geometric": f["geometric"]}, ["ambiguity"])


def test_valley_offset_finds_a_parabolas_bottom_and_clips():
    def r(x, bottom):
        return (x - bottom) ** 2 + 1.0
    for bottom in (-0.2, 0.0, 0.1, 0.3):
        assert Q.valley_offset(r(-0.25, bottom), r(0.0, bottom), r(0.25, bottom), 0.25) == pytest.approx(bottom)
    assert Q.valley_offset(r(-0.25, 2.0), r(0.0, 2.0), r(0.25, 2.0), 0.25) == pytest.approx(0.5)  # two steps
    assert Q.valley_offset(1.0, 2.0, 3.0, 0.25) == -0.25  # no valley: a step towards the lower side
    assert Q.valley_offset(3.0, 2.0, 1.0, 0.25) == 0.25
    assert np.isnan(Q.valley_offset(np.nan, 1.0, 1.0, 0.25))
