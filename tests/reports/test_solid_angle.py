"""Solid-angle weighting of the main metrics (each pixel weighted by cos latitude), checked on hand-computed maps."""

from __future__ import annotations

import math

import numpy as np
import pytest

from reports.metrics import SOLID_ANGLE_KEYS, pooled_summary, solid_angle_weights, summary
from reports.schema import METRIC_COLUMNS

TOL = 1e-12


def _maps(rows_with_error):
    """4 x 8 map, true distance 2 m everywhere, prediction 1 m too far on the given rows, exact elsewhere."""
    gt = np.full((4, 8), 2.0)
    pred = gt.copy()
    pred[list(rows_with_error)] += 1.0
    return pred, gt


def test_weights_are_cos_latitude():
    # rows of a 4-row map: latitudes 67.5, 22.5, -22.5, -67.5 degrees
    np.testing.assert_allclose(solid_angle_weights(4), np.cos(np.radians([67.5, 22.5, 22.5, 67.5])), atol=TOL)


def test_errors_at_the_poles_weigh_less_than_at_the_equator():
    """Half the pixels wrong by 1 m: unweighted MAE 0.5 m either way; weighted by cos latitude the pole rows
    weigh cos 67.5 / (cos 67.5 + cos 22.5) = 1 - 1/sqrt(2) of the sphere and the equator rows 1/sqrt(2)."""
    poles = summary(*_maps([0, 3]))
    equator = summary(*_maps([1, 2]))
    for s in (poles, equator):
        assert s["mae_m"] == pytest.approx(0.5, abs=TOL)
        assert s["outlier_rate"] == pytest.approx(0.5, abs=TOL)
    assert poles["mae_sw_m"] == pytest.approx(1 - 1 / math.sqrt(2), abs=TOL)
    assert equator["mae_sw_m"] == pytest.approx(1 / math.sqrt(2), abs=TOL)
    assert poles["rmse_sw_m"] == pytest.approx(math.sqrt(1 - 1 / math.sqrt(2)), abs=TOL)
    assert poles["absrel_sw"] == pytest.approx((1 - 1 / math.sqrt(2)) / 2.0, abs=TOL)  # error 1 m of 2 m
    assert poles["outlier_rate_sw"] == pytest.approx(1 - 1 / math.sqrt(2), abs=TOL)
    # 3 m for 2 m is a ratio of 1.5 > 1.25: the wrong rows fail delta1, the exact ones pass
    assert poles["delta1_sw"] == pytest.approx(1 / math.sqrt(2), abs=TOL)
    assert equator["delta1_sw"] == pytest.approx(1 - 1 / math.sqrt(2), abs=TOL)
    # weighted median: the wrong rows hold more than half the weight at the equator, less at the poles
    assert equator["median_sw_m"] == 1.0 and poles["median_sw_m"] == 0.0
    # the scored pixels cover the whole sphere: 32 pixels of (2 pi / 8)(pi / 4) sr times cos latitude ~ 4 pi
    assert poles["valid_sr"] == pytest.approx(8 * (2 * np.pi / 8) * (np.pi / 4) * 2 * (np.cos(np.radians(67.5))
                                              + np.cos(np.radians(22.5))), abs=1e-9)
    assert abs(poles["valid_sr"] - 4 * np.pi) < 0.05 * 4 * np.pi


def test_unscored_pixels_carry_no_weight_and_pooling_weighs_by_solid_angle():
    pred, gt = _maps([1])
    gt[2] = np.inf  # row 2 hits nothing: not scored
    s = summary(pred, gt)
    w = np.cos(np.radians(67.5)), np.cos(np.radians(22.5))
    assert s["mae_sw_m"] == pytest.approx(w[1] / (2 * w[0] + w[1]), abs=TOL)
    # two frames pooled = one map holding both
    a, b = _maps([0]), _maps([2])
    pooled = pooled_summary([a, b])
    both = summary(np.concatenate([a[0], b[0]], axis=1), np.concatenate([a[1], b[1]], axis=1))
    for key in SOLID_ANGLE_KEYS[:-1]:
        assert pooled[key] == pytest.approx(both[key], abs=TOL), key


def test_weighted_columns_are_in_the_results_schema():
    assert all(k in METRIC_COLUMNS for k in SOLID_ANGLE_KEYS)
    empty = summary(np.ones((2, 4)), np.full((2, 4), np.inf))
    assert empty["valid_sr"] == 0.0 and math.isnan(empty["mae_sw_m"])
