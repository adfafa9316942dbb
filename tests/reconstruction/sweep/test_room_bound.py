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
