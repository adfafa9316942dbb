"""Ground-truth-free quality measures on an exact ray-cast frame."""

from __future__ import annotations

import numpy as np
import pytest

from harness.jobs.perturb import perturb_frame
from reconstruction import quality as Q
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
