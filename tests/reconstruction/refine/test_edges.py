"""Depth edges moved onto C's image edges (``reconstruction.refine.edges``): a fattened foreground snaps back to the
image's edge, nothing away from depth edges changes, windows wrap in longitude and across the poles."""

import dataclasses

import numba
import numpy as np
import pytest

from reconstruction.methods.sweep import PostParams
from reconstruction.refine.edges import edge_pixels, snap_depth_edges

H, W = 40, 120
NEAR, FAR = 1.0, 3.0
PARAMS = {"radius_px": 5, "sigma_color": 10.0, "sigma_px": 5.0, "jump": 0.05, "reach_px": 4}


def fattened(edge_col: int = 60, spread: int = 3):
    """C's image dark left of ``edge_col`` and bright from it; the estimate's near (left) surface reaches
    ``spread`` columns into the bright side, where the confidence is low (as a sweep's is there)."""
    image = np.full((H, W, 3), 40.0)
    image[:, edge_col:] = 200.0
    d = np.full((H, W), FAR)
    d[:, :edge_col + spread] = NEAR
    conf = np.ones((H, W))
    conf[:, edge_col:edge_col + spread] = 0.05
    return d, conf, image


def test_a_fattened_foreground_snaps_back_to_the_image_edge():
    d, conf, image = fattened()
    out = snap_depth_edges(d, conf, image, **PARAMS)
    assert out.dtype == np.float32 and out.shape == (H, W)
    np.testing.assert_allclose(out[:, 60:63], FAR, rtol=1e-6)  # the bright side takes the far distance
    np.testing.assert_allclose(out[:, 50:60], NEAR, rtol=1e-6)  # the dark side keeps its near one
    np.testing.assert_allclose(out[:, 63:70], FAR, rtol=1e-6)


def test_pixels_away_from_depth_edges_are_untouched():
    d, conf, image = fattened()
    rng = np.random.default_rng(0)
    d = d * np.exp(rng.uniform(-0.005, 0.005, d.shape))  # smooth surfaces: 3 x 3 log spans below the jump
    out = snap_depth_edges(d, conf, image, **PARAMS)
    near_edge = edge_pixels(np.log(d), PARAMS["jump"], PARAMS["reach_px"])
    assert near_edge[:, 60].all() and not near_edge[:, 40].any() and not near_edge[:, 100].any()
    assert np.array_equal(out[~near_edge], d[~near_edge].astype(np.float32))


def test_windows_wrap_in_longitude_and_cross_the_poles():
    d, conf, image = fattened(edge_col=1)  # the dark side is column 0 and, across the seam, nothing: wrap it
    d2, conf2, image2 = (np.roll(a, 59, axis=1) for a in fattened(edge_col=1))
    out = snap_depth_edges(d, conf, image, **PARAMS)
    out2 = snap_depth_edges(d2, conf2, image2, **PARAMS)
    np.testing.assert_allclose(np.roll(out, 59, axis=1), out2, rtol=1e-6)


def test_a_window_crosses_the_pole_half_a_turn_round():
    # rows 0-4 look alike all round; on the near side of the pole they are unsure (2 m), half a turn round sure
    # (4 m); rows 5 on are another colour.  A window at the top row reaches across the pole into the sure side.
    image = np.full((H, W, 3), 200.0)
    image[:5] = 100.0
    d = np.full((H, W), 3.0)
    d[:5, :60], d[:5, 60:] = 2.0, 4.0
    conf = np.ones((H, W))
    conf[:5, :60] = 0.05
    out = snap_depth_edges(d, conf, image, **PARAMS)
    np.testing.assert_allclose(out[0, 10:50], 4.0, rtol=1e-6)  # without the half turn: 2 m (its own side)
    np.testing.assert_allclose(out[:5, 70:110], 4.0, rtol=1e-6)


def test_no_estimate_stays_none_and_is_never_a_neighbour():
    d, conf, image = fattened()
    d[:, 61] = np.nan
    d[5, 58] = -1.0
    out = snap_depth_edges(d, conf, image, **PARAMS)
    assert np.isnan(out[:, 61]).all() and out[5, 58] == -1.0
    np.testing.assert_allclose(out[:, [60, 62]], FAR, rtol=1e-6)
    # a hole in a smooth surface is no depth edge for its neighbours
    flat = np.full((H, W), np.log(2.0))
    flat[10:12, 20:22] = np.nan
    assert not edge_pixels(flat, PARAMS["jump"], 0).any()


def test_radius_zero_changes_nothing_and_bad_input_is_named():
    d, conf, image = fattened()
    assert np.array_equal(snap_depth_edges(d, conf, image, **{**PARAMS, "radius_px": 0}), d.astype(np.float32))
    with pytest.raises(ValueError, match="must match"):
        snap_depth_edges(d, conf[:, :-1], image, **PARAMS)
    with pytest.raises(ValueError, match="sigma_color must be > 0"):
        snap_depth_edges(d, conf, image, **{**PARAMS, "sigma_color": 0.0})
    with pytest.raises(ValueError, match="radius_px and reach_px"):
        snap_depth_edges(d, conf, image, **{**PARAMS, "reach_px": -1})


def test_post_params_check_the_edge_settings():
    assert PostParams().edge_radius_px == 0  # off unless a preset asks
    with pytest.raises(ValueError, match="edge_jump must be > 0"):
        dataclasses.replace(PostParams(), edge_jump=0.0)
    with pytest.raises(ValueError, match="edge_radius_px and edge_reach_px"):
        dataclasses.replace(PostParams(), edge_radius_px=-2)


def test_the_answer_does_not_depend_on_the_number_of_threads():
    # the rows are filtered in parallel, each writing only its own pixels: one thread gives the same answer
    rng = np.random.default_rng(1)
    d, conf, image = fattened()
    d = d * np.exp(rng.uniform(-0.05, 0.05, d.shape))  # edges everywhere: every row has pixels to filter
    conf = rng.uniform(0.0, 1.0, d.shape)
    threads = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = snap_depth_edges(d, conf, image, **PARAMS)
    finally:
        numba.set_num_threads(threads)
    np.testing.assert_allclose(snap_depth_edges(d, conf, image, **PARAMS), one, rtol=1e-6)
