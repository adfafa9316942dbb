"""The room bound's floor and ceiling from the coarse pass's winning labels, and its mirror test."""

import numpy as np
import pytest

from reconstruction.sweep.planes import PlaneParams, dominant_planes, plane_heights

LEVELS = 16
HEIGHTS = plane_heights(PlaneParams())
PER = HEIGHTS.size // 2


def _label(h: float) -> float:
    """The plane label (fractional, from LEVELS on) nearest to height ``h`` (m relative to C)."""
    side = 0 if h < 0 else 1
    k = int(np.argmin(np.abs(np.log(np.abs(HEIGHTS[side * PER:(side + 1) * PER]) / abs(h)))))
    return LEVELS + side * PER + k


def _label_map(shares: dict[float, float], size: int = 20000) -> np.ndarray:
    """A (size // 100, 100) label map: the given share of pixels on each plane height, the rest on sphere labels
    spread over the LEVELS."""
    rng = np.random.default_rng(0)
    out = rng.integers(0, LEVELS, size).astype(np.float64)
    start = 0
    for h, share in shares.items():
        n = int(round(share * size))
        out[start:start + n] = _label(h)
        start += n
    return rng.permutation(out).reshape(-1, 100)


def _close(a: float, b: float) -> bool:
    """Within one plane-label spacing (the heights are 9.5 % apart)."""
    return abs(a - b) <= 0.1 * abs(b)


def test_the_ceilings_mirror_image_in_a_polished_floor_is_not_taken_for_the_floor():
    # floor 1.1 m below C, ceiling 1.9 m above: the mirror image of the ceiling is at 2 * -1.1 - 1.9 = -4.1 m
    label = _label_map({-1.1: 0.15, -4.1: 0.25, 1.9: 0.28})
    z_floor, z_ceil = dominant_planes(label, LEVELS, HEIGHTS, 0.03)
    assert _close(z_floor, -4.1) and _close(z_ceil, 1.9)  # without the test: the mirror image wins
    z_floor, z_ceil = dominant_planes(label, LEVELS, HEIGHTS, 0.03, mirror_tolerance=0.2)
    assert _close(z_floor, -1.1) and _close(z_ceil, 1.9)


def test_the_floors_mirror_image_in_a_glossy_ceiling_is_not_taken_for_the_ceiling():
    label = _label_map({-1.3: 0.3, 1.5: 0.1, 2 * 1.5 + 1.3: 0.2})
    z_floor, z_ceil = dominant_planes(label, LEVELS, HEIGHTS, 0.03, mirror_tolerance=0.2)
    assert _close(z_floor, -1.3) and _close(z_ceil, 1.5)


@pytest.mark.parametrize("shares", [
    {-1.2: 0.3, -0.45: 0.08, 1.8: 0.25},   # a large table top below C: the floor is no mirror image of the ceiling
    {-2.5: 0.3, -1.0: 0.08, 1.9: 0.25},    # a lower floor, a platform nearer: 2 * -1.0 - 1.9 = -3.9, not -2.5
    {-1.1: 0.02, -4.1: 0.25, 1.9: 0.28},   # the nearer plane wins less than min_share: not a floor
])
def test_the_mirror_test_keeps_floors_that_are_not_mirror_images(shares):
    label = _label_map(shares)
    assert dominant_planes(label, LEVELS, HEIGHTS, 0.03, mirror_tolerance=0.2) == \
        dominant_planes(label, LEVELS, HEIGHTS, 0.03)


def test_without_a_ceiling_there_is_no_mirror_test_and_without_planes_no_bound():
    label = _label_map({-1.1: 0.15, -4.1: 0.25})
    z_floor, z_ceil = dominant_planes(label, LEVELS, HEIGHTS, 0.03, mirror_tolerance=0.2)
    assert _close(z_floor, -4.1) and z_ceil == np.inf
    assert dominant_planes(label, LEVELS, np.zeros(0), 0.03, mirror_tolerance=0.2) == (-np.inf, np.inf)


def test_a_penalty_makes_labels_beyond_the_bound_dearer_not_forbidden():
    """``bound_costs`` with a penalty: a sphere label beyond the bound costs that much more (at most the maximum),
    one inside it is untouched, and the horizontal planes beyond it stay forbidden."""
    from reconstruction.sweep.planes import bound_costs

    levels, heights = 4, np.array([-2.0, -1.0, 1.0, 2.0])
    inv_d = np.array([0.2, 0.4, 0.8, 1.6])  # at a_z -0.5 the points lie at z -2.5, -1.25, -0.625, -0.3125 m
    cost = np.array([[[10, 20, 30, 40, 0, 0, 0, 0]]], np.uint16)
    bound_costs(cost, levels, np.array([[-0.5]]), inv_d, heights, -1.5, 1.5, 999, penalty=16)
    np.testing.assert_array_equal(cost[0, 0], [26, 20, 30, 40, 999, 0, 0, 999])
    cost = np.array([[[990, 20, 30, 40, 0, 0, 0, 0]]], np.uint16)
    bound_costs(cost, levels, np.array([[-0.5]]), inv_d, heights, -1.5, 1.5, 999, penalty=16)
    assert cost[0, 0, 0] == 999  # never above the maximum
    cost = np.array([[[10, 20, 30, 40, 0, 0, 0, 0]]], np.uint16)
    bound_costs(cost, levels, np.array([[-0.5]]), inv_d, heights, -1.5, 1.5, 999)  # no penalty: forbidden
    np.testing.assert_array_equal(cost[0, 0, :levels], [999, 20, 30, 40])


def test_near_the_horizon_labels_beyond_the_bound_stay_forbidden():
    """``min_az``: the penalty replaces the ban only where ``|a_z|`` reaches it; a shallower bearing's label beyond
    the bound is forbidden as without a penalty, a steeper one's is dearer."""
    from reconstruction.sweep.planes import bound_costs

    levels, heights = 3, np.array([-1.0, 1.0])
    inv_d = np.array([0.02, 0.2, 1.0])  # at a_z -0.05: z -2.5, -0.25, -0.05 m; at a_z -0.5: z -25, -2.5, -0.5 m
    cost = np.array([[[10, 20, 30, 0, 0], [10, 20, 30, 0, 0]]], np.uint16)
    bound_costs(cost, levels, np.array([[-0.05, -0.5]]), inv_d, heights, -1.5, 1.5, 999, penalty=16, min_az=0.1)
    np.testing.assert_array_equal(cost[0, 0, :levels], [999, 20, 30])  # shallow: forbidden
    np.testing.assert_array_equal(cost[0, 1, :levels], [26, 36, 30])  # steep: dearer
    cost = np.array([[[10, 20, 30, 0, 0]]], np.uint16)
    bound_costs(cost, levels, np.array([[-0.1]]), inv_d, heights, -1.5, 1.5, 999, penalty=16, min_az=0.1)
    np.testing.assert_array_equal(cost[0, 0, :levels], [26, 20, 30])  # |a_z| == min_az: the penalty applies


def test_a_pixel_beyond_the_bound_is_put_on_the_floor_or_the_ceiling_found():
    from reconstruction.sweep.planes import onto_room_planes

    a_z = np.array([[-0.5, -0.5, 0.5, 0.5, 0.0, -0.5]])
    # a reflection 4 m away below the floor (z -2), a floor pixel at 2.6 m (z -1.3), the ceiling's mirror at 5 m
    # above it (z 2.5), a ceiling pixel at 3.4 m (z 1.7), a horizontal bearing, a pixel without an estimate
    d = np.array([[4.0, 2.6, 5.0, 3.4, 8.0, np.nan]], np.float32)
    out, share = onto_room_planes(d, a_z, (-1.43, 1.87), (-1.3, 1.7))
    np.testing.assert_allclose(out[0, :5], [2.6, 2.6, 3.4, 3.4, 8.0], rtol=1e-6)
    assert np.isnan(out[0, 5]) and share == pytest.approx(2 / 6) and out.dtype == np.float32
    out, share = onto_room_planes(d, a_z, (-np.inf, np.inf), (-np.inf, np.inf))  # no bound: nothing moves
    np.testing.assert_array_equal(out, d)
    assert share == 0.0
    a_z = np.array([[-0.05, -0.5, 0.05, 0.5]])  # near the horizon nothing moves with min_az 0.1
    d = np.array([[40.0, 4.0, 50.0, 5.0]], np.float32)
    out, share = onto_room_planes(d, a_z, (-1.43, 1.87), (-1.3, 1.7), min_az=0.1)
    np.testing.assert_allclose(out[0], [40.0, 2.6, 50.0, 3.4], rtol=1e-6)
    assert share == pytest.approx(2 / 4)


def test_a_negative_or_non_finite_penalty_is_refused():
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="bound_penalty"):
            PlaneParams(bound_penalty=bad)
    for bad in (-0.1, 1.0, float("nan")):
        with pytest.raises(ValueError, match="bound_penalty_min_az"):
            PlaneParams(bound_penalty_min_az=bad)


def test_the_distance_to_the_room_plane_along_each_bearing():
    """Down to the floor, up to the ceiling (metres = height / a_z); inf for a horizontal bearing or a plane not
    found."""
    from reconstruction.sweep.planes import room_plane_distance

    a_z = np.array([[-0.5, -1.0, 0.5, 1.0, 0.0]])
    d = room_plane_distance(a_z, (-1.3, 1.7))
    assert d.dtype == np.float32
    np.testing.assert_allclose(d[0, :4], [2.6, 1.3, 3.4, 1.7], rtol=1e-6)
    assert np.isinf(d[0, 4])
    assert np.isinf(room_plane_distance(a_z, (-np.inf, np.inf))).all()
    none_up = room_plane_distance(a_z, (-1.3, np.inf))
    np.testing.assert_allclose(none_up[0, :2], [2.6, 1.3], rtol=1e-6)
    assert np.isinf(none_up[0, 2:]).all()
