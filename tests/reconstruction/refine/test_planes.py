"""The floor's and the ceiling's offsets searched from the images (reconstruction.refine.planes) on exact ray-cast
frames."""

import dataclasses

import numpy as np
import pytest

from reconstruction.camera.equirect import bearing_grid
from reconstruction.refine.planes import PlaneFit, PlaneRefineParams, _pick, refine_plane, snap_to_planes
from reconstruction.sweep.cost import gray_float
from reconstruction.sweep.planes import UP
from tests.helpers import make_synthetic_frame


@pytest.fixture(scope="module")
def box():
    """A 240x120 synthetic_box frame, its gray images, world bearings, true distance and floor height (m)."""
    frame = make_synthetic_frame(240)
    bearings = bearing_grid(frame.width, frame.height, frame.cameras["C"].rotation)
    truth = frame.distance["C"].astype(np.float64)
    z = truth * bearings[..., 2]
    floor = float(np.median(z[bearings[..., 2] < -0.5]))
    gray = {k: gray_float(frame.images[k], 0.0) for k in ("C", "U", "R")}
    return frame, gray, bearings, truth, floor


def _floor_moved(truth, bearings, floor, scale):
    """The true distance with the floor's pixels (within 0.5 % of its height) moved by ``scale``."""
    d = truth.copy()
    on_floor = np.abs(truth * bearings[..., 2] / floor - 1.0) < 0.005
    d[on_floor] *= scale
    return d, on_floor


@pytest.mark.parametrize("scale", [1.0, 1.05, 0.95])
def test_a_floor_put_a_few_per_cent_off_is_found_again_within_half_a_per_cent(box, scale):
    frame, gray, bearings, truth, floor = box
    d, on_floor = _floor_moved(truth, bearings, floor, scale)
    fit = refine_plane(gray, frame.cameras, bearings, d, UP, floor * scale)
    assert fit.applied
    assert fit.offset_before == pytest.approx(floor * scale, rel=0.003)  # where the estimate has it
    assert fit.offset == pytest.approx(floor, rel=0.005)
    assert 0 < fit.se < 0.005 and fit.pixels > 1000 and fit.blocks >= 4
    snapped = snap_to_planes(d, bearings, [fit])
    assert np.median(np.abs(snapped[on_floor] / truth[on_floor] - 1.0)) < 0.005
    assert np.median(np.abs(d[on_floor] / truth[on_floor] - 1.0)) == pytest.approx(abs(scale - 1.0), abs=1e-3)


def test_the_search_starts_from_where_the_estimate_has_the_plane_not_from_where_it_was_told(box):
    frame, gray, bearings, truth, floor = box
    d, _ = _floor_moved(truth, bearings, floor, 1.04)
    fit = refine_plane(gray, frame.cameras, bearings, d, UP, floor * 1.1)  # told 10 % off, the estimate 4 %
    assert fit.offset_start == pytest.approx(floor * 1.1)
    assert fit.offset_before == pytest.approx(floor * 1.04, rel=0.003)
    assert fit.offset == pytest.approx(floor, rel=0.005)


def test_images_without_texture_leave_the_plane_where_it_was(box):
    frame, gray, bearings, truth, floor = box
    flat = {k: np.full_like(v, 120.0) for k, v in gray.items()}
    d, _ = _floor_moved(truth, bearings, floor, 1.05)
    fit = refine_plane(flat, frame.cameras, bearings, d, UP, floor * 1.05)
    assert not fit.applied and fit.offset == fit.offset_before
    assert snap_to_planes(d, bearings, [fit]).tolist() == d.astype(np.float32).tolist()


def test_a_strict_standard_error_or_basin_keeps_the_plane(box):
    frame, gray, bearings, truth, floor = box
    d, _ = _floor_moved(truth, bearings, floor, 1.05)
    for strict in ({"max_se": 1e-6}, {"max_basin": 1e-6}):
        fit = refine_plane(gray, frame.cameras, bearings, d, UP, floor * 1.05,
                           dataclasses.replace(PlaneRefineParams(), **strict))
        assert not fit.applied and fit.offset == pytest.approx(floor * 1.05, rel=0.003)
        assert np.isfinite(fit.se)


def test_of_two_minima_alike_the_farther_is_the_plane_and_a_clearly_lower_one_wins():
    x = np.linspace(-1, 1, 41)
    near, far = 1.0 + (x + 0.5) ** 2, 1.0 + (x - 0.4) ** 2  # mean costs: never near 0
    curve = np.minimum(near, far + 0.02)  # the nearer minimum 2 % lower
    assert abs(x[_pick(curve, 0.05)] - 0.4) < 0.06
    curve = np.minimum(near, far + 0.2)  # the farther one 20 % higher: not a candidate
    assert abs(x[_pick(curve, 0.05)] + 0.5) < 0.06
    assert _pick(np.linspace(2.0, 1.0, 11), 0.05) == 10  # no interior minimum: the least


def test_snapping_moves_only_the_pixels_near_an_applied_plane_within_the_range():
    bearings = bearing_grid(40, 20)
    a_z = bearings[..., 2]
    floor = np.where(a_z < -0.2, -1.0 / np.minimum(a_z, -1e-3), 5.0)  # a floor 1 m below C, 5 m elsewhere
    d = floor * 1.04
    d[a_z >= -0.2] = 5.0
    fit = PlaneFit(normal=(0.0, 0.0, 1.0), offset_start=-1.04, offset_before=-1.04, offset=-1.0, se=0.001, pixels=1,
                   blocks=8, applied=True)
    out = snap_to_planes(d, bearings, [fit])
    below = a_z < -0.2
    np.testing.assert_allclose(out[below], floor[below], rtol=1e-5)
    assert (out[~below] == 5.0).all()
    assert snap_to_planes(d, bearings, [dataclasses.replace(fit, applied=False)]).tolist() == \
        d.astype(np.float32).tolist()
    capped = snap_to_planes(d, bearings, [fit], d_range=(0.0, 1.5))  # a snapped pixel never leaves the range
    assert (capped <= np.maximum(d, 1.5) + 1e-6).all()
    np.testing.assert_allclose(capped[below & (floor > 1.5)], d[below & (floor > 1.5)].astype(np.float32))


@pytest.mark.parametrize("bad", [{"select": 0.0}, {"steps": 3}, {"min_cos": 1.0}, {"max_se": -1.0},
                                 {"longitude_blocks": 1}, {"min_gradient": -1.0}])
def test_bad_parameters_are_refused_in_one_line(bad):
    with pytest.raises(ValueError, match="plane refinement"):
        PlaneRefineParams(**bad)


@pytest.mark.slow
def test_the_default_records_and_applies_its_floor_and_ceiling_search(box):
    """fused-mirror on the ray-cast box: both planes searched and applied, the floor within half a per cent of the
    truth and the ceiling within one (its R pair puts it about 0.5 % near at this width, 0.2 % at 800 px), its walls
    recorded after them (a box: nothing seen beyond them), and the answer closer to the truth than the same method
    without the search."""
    from reconstruction.methods.presets import fused_mirror

    frame, _, bearings, truth, floor = box
    method = fused_mirror()
    out = method.run(frame)
    planes = [p for p in out.info["planes"] if "se" in p]
    walls = out.info["planes"][len(planes):]
    assert [p["normal"] for p in planes] == [[0.0, 0.0, 1.0]] * 2 and all(p["applied"] for p in planes)
    assert walls and all(w["normal"][2] == 0 and w["applied"] and w["beyond_share"] <= 0.03 for w in walls)
    ceiling = float(np.median((truth * bearings[..., 2])[bearings[..., 2] > 0.5]))
    assert planes[0]["offset"] == pytest.approx(floor, rel=0.005)
    assert planes[1]["offset"] == pytest.approx(ceiling, rel=0.01)
    assert out.seconds["refine_planes"] >= 0
    without = dataclasses.replace(method, sweep=dataclasses.replace(method.sweep, refine_planes=None)).run(frame)
    assert "planes" not in without.info
    ok = np.isfinite(truth)
    assert np.abs(out.distance - truth)[ok].mean() < np.abs(without.distance - truth)[ok].mean()


def _box_room(width=240, x=(1.5, 2.5), y=(2.0, 4.0), z=(1.3, 1.5)):
    """C's world bearings and the exact distances to a box room around it: by default 4 x 6 x 2.8 m (walls at x =
    -1.5, 2.5 and y = -2, 4, floor -1.3, ceiling 1.5 m; each pair the distances below and above C, metres)."""
    b = bearing_grid(width, width // 2, np.eye(3))
    with np.errstate(divide="ignore", invalid="ignore"):
        hits = [np.where(b[..., i] * s > 0, o / (b[..., i] * s), np.inf)
                for i, pair in enumerate((x, y, z)) for s, o in zip((-1, 1), pair, strict=True)]
    return b, np.min(hits, axis=0)


def test_mirror_images_beyond_an_enclosing_wall_are_put_on_it_and_an_open_wall_is_left_alone():
    from reconstruction.refine.planes import onto_walls
    from reconstruction.sweep.planes import room_walls

    b, d = _box_room()
    _, walls = room_walls(d[..., None] * b, 0.01)
    assert sorted(round(abs(o), 3) for _, o in walls) == [1.5, 2.0, 2.5, 4.0]
    params = PlaneRefineParams(wall_margin=0.2, wall_max_share=0.03)
    on_x = np.abs(d * b[..., 0] - 2.5) < 1e-6  # the wall at x = 2.5
    rows, cols = np.nonzero(on_x)
    mirror = np.zeros(d.shape, bool)
    mirror[rows[:40], cols[:40]] = True  # a screen's mirror image: 40 of its pixels matched 1.6x too far
    seen = d.copy()
    seen[mirror] *= 1.6
    seen[rows[40], cols[40]] = np.nan
    out, records = onto_walls(seen, b, walls, params)
    np.testing.assert_allclose(out[mirror], d[mirror], rtol=1e-4)  # on the wall as the map's offsets place it
    assert np.isnan(out[rows[40], cols[40]]) and out.dtype == np.float32
    others = ~mirror & np.isfinite(seen)
    np.testing.assert_array_equal(out[others], seen[others].astype(np.float32))
    assert all(r["applied"] for r in records) and max(r["beyond_share"] for r in records) < 0.03
    # half the wall's pixels 1.6x beyond it: an opening, not a mirror; the wall is left alone
    half = on_x & (np.arange(d.shape[1])[None, :] % 2 == 0)
    opened = d.copy()
    opened[half] *= 1.6
    out, records = onto_walls(opened, b, walls, params)
    assert np.all(out[half] > d[half] * 1.001)  # none on that wall (those beyond another one, near corners, on it)
    assert np.mean(out[half] == opened[half].astype(np.float32)) > 0.8
    assert [r["applied"] for r in records if abs(r["offset"] - 2.5) < 1e-3] == [False]
    # a pixel 10 % beyond its wall: within the margin, left where it is
    near = seen.copy()
    near[mirror] = d[mirror] * 1.1
    out, _ = onto_walls(near, b, walls, params)
    np.testing.assert_allclose(out[mirror], near[mirror], rtol=1e-6)


def test_a_wall_with_more_beyond_it_encloses_when_the_ceiling_stops_at_it_and_a_shelf_does_not():
    from reconstruction.refine.planes import onto_walls

    b, d = _box_room()  # walls at x = -1.5 and 2.5, ceiling 1.5 m above C
    lon, lat = np.arctan2(b[..., 1], b[..., 0]), np.arcsin(b[..., 2])
    wall = [(np.array([1.0, 0.0, 0.0]), 2.5)]
    # a screen on the wall at x = 2.5, below the ceiling: its mirror images matched 1.6x beyond it
    screen = (np.abs(lon) < np.radians(30)) & (np.abs(lat) < np.radians(15))
    seen = np.where(screen, d * 1.6, d)
    strict = PlaneRefineParams(wall_margin=0.2, wall_max_share=0.03)
    out, records = onto_walls(seen, b, wall, strict, ceiling=1.5)
    assert records[0]["beyond_share"] > 0.03 and not records[0]["applied"]  # too much beyond it for the share alone
    np.testing.assert_array_equal(out, seen.astype(np.float32))
    closed = dataclasses.replace(strict, closed_max_share=0.5, closed_ceiling_share=0.04)
    out, records = onto_walls(seen, b, wall, closed, ceiling=1.5)
    assert records[0]["applied"] and records[0]["ceiling_beyond_share"] == 0.0
    np.testing.assert_allclose(out[screen], d[screen], rtol=1e-4)  # back on the wall
    # without the ceiling's height only the share decides
    _, records = onto_walls(seen, b, wall, closed)
    assert not records[0]["applied"] and "ceiling_beyond_share" not in records[0]
    # a shelf at x = 1.8 that stops 0.5 m above C in a room whose wall is at x = 5: the room and its ceiling go
    # on behind it
    b, d = _box_room(x=(1.5, 5.0))
    shelf = [(np.array([1.0, 0.0, 0.0]), 1.8)]
    with np.errstate(divide="ignore", invalid="ignore"):
        on_shelf = (b[..., 0] > 0) & (1.8 / b[..., 0] < d) & (1.8 / b[..., 0] * b[..., 2] < 0.5)
    shelved = np.where(on_shelf, 1.8 / np.where(b[..., 0] > 0, b[..., 0], 1.0), d)
    out, records = onto_walls(shelved, b, shelf, closed, ceiling=1.5)
    assert records[0]["beyond_share"] <= 0.5 and records[0]["ceiling_beyond_share"] > 0.1
    assert not records[0]["applied"]
    np.testing.assert_array_equal(out, shelved.astype(np.float32))


def test_wall_parameters_out_of_range_are_refused():
    for bad in ({"wall_margin": -0.1}, {"wall_max_share": 1.5}, {"wall_max_share": float("nan")}):
        with pytest.raises(ValueError, match="wall_margin"):
            PlaneRefineParams(**bad)


def test_the_ceilings_edge_is_where_its_area_ends_and_only_the_ceiling_counts():
    from reconstruction.refine.planes import ceiling_walls

    b, d = _box_room()
    normals = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    walls = {(int(np.argmax(np.abs(n))), np.sign(o)): o for n, o in ceiling_walls(d, b, 1.5, normals, 1.0)}
    # the whole ceiling's area: its farthest pixel centres, within a pixel's footprint of the walls
    for key, wall in {(0, -1): -1.5, (0, 1): 2.5, (1, -1): -2.0, (1, 1): 4.0}.items():
        assert walls[key] == pytest.approx(wall, rel=0.03) and abs(walls[key]) <= abs(wall) + 1e-9
    # 99 % of a side's area: at most the whole area's edge, within a few per cent of the wall
    at99 = {(int(np.argmax(np.abs(n))), np.sign(o)): o for n, o in ceiling_walls(d, b, 1.5, normals, 0.99)}
    for key, wall in walls.items():
        assert abs(wall) * 0.96 <= abs(at99[key]) <= abs(wall) + 1e-9
    # the floor and the walls do not count: the same edges with everything but the ceiling at half its distance
    # (none of it at the ceiling's height) ...
    near = np.where(np.abs(d * b[..., 2] - 1.5) < 0.02 * 1.5, d, d * 0.5)
    assert [o for _, o in ceiling_walls(near, b, 1.5, normals, 0.99)] == pytest.approx(list(at99.values()))
    # ... and without ceiling pixels (or too few of them) there is no edge
    assert ceiling_walls(d, b, 2.5, normals, 0.99) == []
    assert ceiling_walls(d, b, 1.5, normals, 0.99, min_share=0.5) == []


def test_a_long_rooms_far_ceiling_counts_by_its_area_not_its_pixels():
    from reconstruction.refine.planes import ceiling_walls

    # a 2 m wide, 30 m long corridor (x from -1 to 1, y from -15 to 15), ceiling 1.2 m above C
    b, d = _box_room(1000, (1.0, 1.0), (15.0, 15.0), (1.4, 1.2))
    walls = ceiling_walls(d, b, 1.2, np.array([[0.0, 1.0, 0.0]]), 0.99)
    # (a far pixel's footprint is a metre long near the end, so the edge is within a footprint of the wall)
    assert [o / 15.0 for _, o in walls] == pytest.approx([-0.975, 0.975], abs=0.026)
    # counted by pixels, 99 % of the ceiling's pixels lie within two fifths of its length
    on = np.abs(d * b[..., 2] - 1.2) < 0.024
    assert np.quantile(np.abs(d[on] * b[on][:, 1]), 0.99) < 0.4 * 15.0


def test_where_no_wall_found_encloses_a_side_the_ceilings_edge_takes_its_mirror_images():
    from reconstruction.refine.planes import onto_enclosing_walls
    from reconstruction.sweep.planes import room_walls

    b, d = _box_room()
    _, walls = room_walls(d[..., None] * b, 0.01)
    normals = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    # on the side of the wall at x = 2.5 the surface found is a bench's front at x = 0.6, which encloses nothing
    found = [(n, o) for n, o in walls if not (abs(n[0]) > 0.9 and o * np.sign(n[0]) > 0)]
    found.append((np.array([1.0, 0.0, 0.0]), 0.6))
    on_x = np.abs(d * b[..., 0] - 2.5) < 1e-6
    mirror = on_x & (np.abs(b[..., 2]) < 0.2) & (np.abs(b[..., 1]) < 0.3)  # a cabinet's mirror images, 1.8 x too far
    seen = np.where(mirror, d * 1.8, d)
    off = PlaneRefineParams(wall_margin=0.2, wall_max_share=0.06)
    out, records = onto_enclosing_walls(seen, b, found, normals, 1.5, off)
    np.testing.assert_array_equal(out[mirror], seen[mirror].astype(np.float32))  # not looked for: left alone
    assert not any("from" in r for r in records)
    on = dataclasses.replace(off, ceiling_edge=0.99)
    out, records = onto_enclosing_walls(seen, b, found, normals, 1.5, on)
    np.testing.assert_allclose(out[mirror], d[mirror], rtol=0.03)  # on the ceiling's edge, a per cent short
    edges = [r for r in records if r.get("from") == "ceiling"]
    # one edge on the side the bench left open; the sides whose walls enclose get none
    assert len(edges) == 1 and edges[0]["applied"] and edges[0]["offset"] == pytest.approx(2.5 * 0.99, abs=0.06)
    others = ~mirror
    np.testing.assert_array_equal(out[others], seen[others].astype(np.float32))
    # no wall direction or no ceiling: the walls found only
    for normals_, ceiling in ((None, 1.5), (normals, None)):
        out, records = onto_enclosing_walls(seen, b, found, normals_, ceiling, on)
        np.testing.assert_array_equal(out[mirror], seen[mirror].astype(np.float32))


def test_closed_wall_shares_out_of_range_are_refused():
    for bad in ({"closed_max_share": -0.1}, {"closed_ceiling_share": 1.5}, {"closed_max_share": float("nan")}):
        with pytest.raises(ValueError, match="closed_max_share"):
            PlaneRefineParams(**bad)


def test_a_ceiling_edge_quantile_out_of_range_is_refused():
    for bad in (-0.1, 1.5, float("nan")):
        with pytest.raises(ValueError, match="ceiling_edge"):
            PlaneRefineParams(ceiling_edge=bad)


def test_a_corridor_whose_two_ends_are_not_found_keeps_its_far_end():
    from reconstruction.refine.planes import onto_enclosing_walls

    # a 2 m wide, 30 m long corridor whose far ceiling (beyond 8 m) the estimate puts 30 % too far: the ceiling's
    # edge, at about 8 m, is short of both ends (the pixels within 1 % of the ceiling's height count as its own)
    b, d = _box_room(480, (1.0, 1.0), (15.0, 15.0), (1.4, 1.2))
    ceiling = np.abs(d * b[..., 2] - 1.2) < 1e-6
    seen = np.where(ceiling & (np.abs(d * b[..., 1]) > 8.0), d * 1.3, d)
    normals = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    sides = [(normals[0], -1.0), (normals[0], 1.0)]
    params = PlaneRefineParams(wall_margin=0.2, wall_max_share=0.06, ceiling_edge=0.99, snap=0.01)
    out, records = onto_enclosing_walls(seen, b, sides, normals, 1.2, params)
    off, _ = onto_enclosing_walls(seen, b, sides, normals, 1.2, dataclasses.replace(params, ceiling_edge=0.0))
    np.testing.assert_array_equal(out, off)  # the side walls' step only
    assert not any("from" in r for r in records)
    # with one end found, the other is looked for at the ceiling's edge (and here put too near: why it is not
    # looked for when neither end is found)
    out, records = onto_enclosing_walls(seen, b, [*sides, (normals[1], -15.0)], normals, 1.2, params)
    edges = [r for r in records if r.get("from") == "ceiling"]
    assert len(edges) == 1 and 7.0 < edges[0]["offset"] < 8.5 and edges[0]["applied"]
    far_end = np.abs(d * b[..., 1] - 15.0) < 1e-6
    assert np.all(out[far_end] < d[far_end] * 0.6)
    # an edge farther than the rig resolves the ceiling is not used
    out, records = onto_enclosing_walls(seen, b, [*sides, (normals[1], -15.0)], normals, 1.2, params, max_edge_m=7.0)
    assert not any("from" in r for r in records)


def test_the_resolved_range_grows_with_the_baseline_the_width_and_the_band():
    from reconstruction.refine.planes import EDGE_RESOLUTION_PX, resolved_range

    r = resolved_range(0.4, 1000, 0.06)
    assert r == pytest.approx(7.64, abs=0.01)
    # a quarter pixel at that distance moves a point square on to the baseline by half the band
    assert EDGE_RESOLUTION_PX * 2 * np.pi / 1000 * r / 0.4 == pytest.approx(0.03)
    assert resolved_range(0.8, 1000, 0.06) == pytest.approx(2 * r)
    assert resolved_range(0.4, 2000, 0.06) == pytest.approx(2 * r)
    assert resolved_range(0.4, 1000, 0.12) == pytest.approx(2 * r)
