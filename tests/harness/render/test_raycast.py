"""The numpy ray-caster (``harness.render.raycast``) and the ``synthetic_box`` scene: exact ground truth, no Blender.

Tolerances:
* float64 distances: 1e-12 m.  The slab test does a handful of correctly rounded float64 operations on
  numbers of a few metres (one ulp at 8 m is 1.8e-15 m), so a correct implementation errs by ~1e-14 m at
  most; any convention or geometry bug errs by centimetres or more.
* stored (float32) distances: one float32 ulp relative (2**-23): rounding float64 to float32 errs by at
  most half of that.
* cross-camera agreement: 1e-6 relative, well above the float64 error of project/unproject round trips
  (~1e-13) and far below any geometric mistake (a 1-pixel pose error at 128 px wide moves points by ~5%).
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

import harness
from harness.data.frame import read_frame, write_frame
from harness.render.raycast import (
    AMBIENT,
    ENGINE,
    TEXTURES,
    RaycastRenderer,
    SurfacePoints,
    albedo,
    fbm,
    raycast,
    render_camera,
    render_frame,
    value_noise,
)
from reconstruction.camera.equirect import bearing_grid, pixel_to_bearing, project
from reconstruction.camera.rig import CAMERA_NAMES, Rig, yaw_rotation
from scenes.model import Box, Cylinder, Light, Material, SceneSpec, Sphere, choose_viewpoints
from scenes.registry import get_scene

F32_ULP = 2.0 ** -23
ROOM = (6.0, 5.0, 3.0)


def room_spec(*solids: Box, yaw: float = 0.0, center=(0.0, 0.0, 1.5), contrast: float = 0.4) -> SceneSpec:
    spec = SceneSpec(name="test_room")
    spec.add_material(Material("wall", kind="noise", scale=0.3, contrast=contrast))
    spec.add_material(Material("solid", kind="paint", color=(0.2, 0.5, 0.8), scale=0.2, contrast=contrast))
    spec.boxes.append(Box(center=center, size=ROOM, material="wall", yaw=yaw, inward=True, name="room"))
    spec.boxes.extend(solids)
    spec.lights.append(Light("point", position=(0.5, 0.5, 2.5), power=60.0))
    return spec


def closed_form_room_distance(origin, directions, center, size, yaw):
    """Distance from ``origin`` (inside) to the walls of a box room yawed by ``yaw``, written independently:
    per axis of the room frame, the wall the ray moves toward is at (bound - o) / d; the nearest wins."""
    rot = yaw_rotation(yaw)
    o = (np.asarray(origin) - np.asarray(center)) @ rot  # room-frame coordinates
    d = directions @ rot
    half = np.asarray(size) / 2.0
    with np.errstate(divide="ignore"):
        t_axis = np.where(d > 0, (half - o) / d, (-half - o) / d)
    return t_axis.min(axis=1) * np.linalg.norm(directions, axis=1)


# ------------------------------------------------------------------------------------------ exact geometry


@pytest.mark.parametrize("yaw", [0.0, 0.5, -2.0])
def test_empty_room_distance_equals_closed_form(yaw):
    origin = np.array([0.7, -0.4, 1.2])
    center = (0.3, 0.1, 1.5)
    spec = room_spec(yaw=yaw, center=center)
    dirs = bearing_grid(96, 48).reshape(-1, 3)
    t, box, face, pts = raycast(spec, origin, dirs)
    expected = closed_form_room_distance(origin, dirs, center, ROOM, yaw)
    assert np.all(box == 0)
    assert np.max(np.abs(t - expected)) < 1e-12  # metres
    # the hit points lie on the wall planes (room frame), on the face reported
    local = (pts - np.asarray(center)) @ yaw_rotation(yaw)
    axis, side = face // 2, face % 2
    plane = np.where(side == 1, 1.0, -1.0) * np.asarray(ROOM)[axis] / 2.0
    assert np.max(np.abs(local[np.arange(len(local)), axis] - plane)) < 1e-12


def test_frame_distance_is_the_float32_closed_form():
    spec = room_spec()
    rig = Rig(position=np.array([0.7, -0.4, 1.2]), yaw_rad=0.3)
    frame = render_frame(spec, rig, 64, "test_room", "vp", supersample=1)
    for name, pose in frame.cameras.items():
        dirs = bearing_grid(64, 32, pose.rotation).reshape(-1, 3)
        exact = closed_form_room_distance(pose.position, dirs, (0, 0, 1.5), ROOM, 0.0).reshape(32, 64)
        err = np.abs(frame.distance[name].astype(np.float64) - exact)
        assert np.all(err <= F32_ULP * exact), name


def test_inner_box_occludes():
    cube = Box(center=(2.0, 0.0, 1.2), size=(0.5, 0.5, 0.5), material="solid", name="cube")
    turned = Box(center=(0.0, 2.0, 1.2), size=(0.5, 0.5, 0.5), material="solid", yaw=np.pi / 4, name="turned")
    spec = room_spec(cube, turned)
    origin = np.array([0.0, 0.0, 1.2])
    dirs = np.array([[1.0, 0.0, 0.0],     # straight at the cube's -x face
                     [-1.0, 0.0, 0.0],    # the -x wall, nothing in between
                     [1.0, 0.16, 0.0],     # passes beside the cube (y = 0.28 at its near face) to the +x wall
                     [0.0, 1.0, 0.0],     # at the 45-degree-turned box's edge... its corner faces us
                     [0.0, 0.0, -1.0]])   # the floor
    t, box, face, pts = raycast(spec, origin, dirs)
    norm = np.linalg.norm(dirs, axis=1)
    dist = t * norm
    assert dist[0] == pytest.approx(1.75, abs=1e-12) and box[0] == 1 and face[0] == 0
    assert dist[1] == pytest.approx(3.0, abs=1e-12) and box[1] == 0
    assert box[2] == 0 and dist[2] == pytest.approx(3.0 * np.hypot(1.0, 0.16), abs=1e-12)
    assert box[3] == 2 and dist[3] == pytest.approx(2.0 - 0.25 * np.sqrt(2.0), abs=1e-12)
    assert box[4] == 0 and face[4] == 4 and dist[4] == pytest.approx(1.2, abs=1e-12)
    np.testing.assert_allclose(pts[0], [1.75, 0.0, 1.2], atol=1e-12)
    # a ray that misses everything (origin outside the room, pointing away) reports no hit
    t, box, face, pts = raycast(spec, np.array([10.0, 0.0, 1.0]), np.array([[1.0, 0.0, 0.0]]))
    assert np.isinf(t[0]) and box[0] == -1 and face[0] == -1 and np.isnan(pts[0]).all()


def test_random_rays_against_a_yawed_box_agree_with_box_contains():
    """Independent check of the rotated slab test with ``Box.contains`` (scenes.model's own point test)."""
    rng = np.random.default_rng(11)
    box = Box(center=(0.3, -0.2, 0.9), size=(1.1, 0.5, 0.7), material="solid", yaw=0.7)
    spec = room_spec(box)
    spec.boxes = [box]
    origins = rng.uniform(-3, 3, (4000, 3))
    origins = origins[~box.contains(origins, 0.01)]
    dirs = rng.normal(size=origins.shape)
    dirs[: len(dirs) // 2] = np.asarray(box.center) - origins[: len(dirs) // 2]  # half aimed at the box
    dirs += rng.normal(scale=0.2, size=dirs.shape)
    t, idx, face, pts = raycast(spec, origins, dirs)
    hit = idx == 0
    assert 0.3 < hit.mean() < 0.9
    # hits are on the surface: inside the box grown by 1e-9 m, outside it shrunk by 1e-9 m
    assert box.contains(pts[hit], 1e-9).all() and not box.contains(pts[hit], -1e-9).any()
    # and nothing of the box lies before them, nor anywhere along a missing ray (sampled every ~1 cm)
    for frac in np.linspace(0.0, 0.999, 50):
        assert not box.contains(origins[hit] + frac * t[hit, None] * dirs[hit]).any()
    steps = np.linspace(0.0, 8.0, 800)[:, None, None] * dirs[~hit] / np.linalg.norm(dirs[~hit], axis=1)[:, None]
    assert not box.contains((origins[~hit] + steps).reshape(-1, 3)).any()
    # the face index names the face the point is on
    local = (pts[hit] - box.center) @ yaw_rotation(box.yaw)
    axis, side = face[hit] // 2, face[hit] % 2
    on = local[np.arange(hit.sum()), axis]
    np.testing.assert_allclose(np.abs(on), np.asarray(box.size)[axis] / 2, atol=1e-12)
    assert np.all((on > 0) == (side == 1))


# ------------------------------------------------------------------------------------------ conventions


def test_box_at_plus_x_appears_at_three_quarters_width_and_plus_z_on_top_rows():
    w, h = 128, 64
    right = Box(center=(2.0, 0.0, 1.2), size=(0.4, 0.4, 0.4), material="solid", name="right")
    above = Box(center=(0.0, 0.0, 2.5), size=(0.6, 0.6, 0.2), material="solid", name="above")
    spec = room_spec(right, above)
    image, dist = render_camera(spec, (0.0, 0.0, 1.2), yaw_rotation(0.0), w, supersample=1)
    t, box, _, _ = raycast(spec, (0.0, 0.0, 1.2), bearing_grid(w, h, yaw_rotation(0.0)).reshape(-1, 3))
    box = box.reshape(h, w)
    v, u = np.nonzero(box == 1)
    assert len(u) > 10
    assert np.mean(u) + 0.5 == pytest.approx(0.75 * w, abs=0.5)  # looking right (+X)
    assert np.mean(v) + 0.5 == pytest.approx(0.5 * h, abs=0.5)   # on the horizon
    assert np.all(dist[box == 1] < 2.0) and np.all(dist[box != 1] > 0.9)
    v, _ = np.nonzero(box == 2)
    assert v.max() < 0.25 * h and np.all(box[0] == 2)           # the box above fills the top rows
    np.testing.assert_allclose(dist[0], 1.2, rtol=0.05)          # ~1.2 m straight up to its bottom face


# ------------------------------------------------------------------------------------------ cross-camera


@pytest.fixture(scope="module")
def box_frame():
    entry, preset = get_scene("synthetic_box:cluttered")
    spec = entry.spec(preset, seed=3)
    rig = choose_viewpoints(spec, 2, seed=1)[1]  # a random placement and yaw, not the centred default
    return spec, rig, render_frame(spec, rig, 160, "synthetic_box", "vp1", supersample=2)


def _c_surface_points(spec, frame):
    c = frame.cameras["C"]
    dirs = bearing_grid(frame.width, frame.height, c.rotation).reshape(-1, 3)
    t, _, _, pts = raycast(spec, c.position, dirs)
    # the frame's C distance is the float32 of this exact ray-cast
    np.testing.assert_allclose(frame.distance["C"].ravel(), t, rtol=F32_ULP)
    return pts


def _seen_from(box_frame, other):
    """C's surface points projected into camera ``other``: the frame, (u, v) there, the distance ``other``
    ray-casts along that direction and the distance it should be if the point is visible."""
    spec, rig, frame = box_frame
    pts = _c_surface_points(spec, frame)
    pose = frame.cameras[other]
    u, v = project(pts, pose.position, pose.rotation, frame.width, frame.height)
    dirs = pixel_to_bearing(u, v, frame.width, frame.height) @ pose.rotation.T
    t, _, _, _ = raycast(spec, pose.position, dirs)
    return frame, u, v, t, np.linalg.norm(pts - pose.position, axis=1)


@pytest.mark.parametrize("other", ["U", "R"])
def test_cameras_agree_on_geometry(box_frame, other):
    frame, u, v, t, expected = _seen_from(box_frame, other)
    rel = (t - expected) / expected
    seen = np.abs(rel) < 1e-6
    assert seen.mean() > 0.85, f"{other} sees only {seen.mean():.1%} of C's surface points"
    # wherever the other camera does not see C's point, something must stand in front of it: never behind
    assert np.all(rel[~seen] < 0), f"{other}: {np.sum(rel[~seen] > 0)} points seen beyond C's surface"
    if other == "R":  # this placement has furniture hiding some of C's surface from R: the check bites
        assert (~seen).sum() > 20
    # and the stored distance map agrees (bilinear sampling; away from depth edges)
    d_other = cv2.remap(frame.distance[other], u.reshape(frame.height, -1).astype(np.float32),
                        v.reshape(frame.height, -1).astype(np.float32), cv2.INTER_LINEAR,
                        borderMode=cv2.BORDER_WRAP).ravel()
    close = np.abs(d_other - expected) < 0.01 * expected
    assert close[seen].mean() > 0.9


@pytest.mark.parametrize("other", ["U", "R"])
def test_cameras_agree_on_colour(box_frame, other):
    frame, u, v, t, expected = _seen_from(box_frame, other)
    seen = (np.abs(t - expected) < 1e-6 * expected).reshape(frame.height, frame.width)
    seen[:4] = seen[-4:] = False  # poles: bilinear sampling across the pole is not meaningful
    warped = cv2.remap(frame.images[other], u.reshape(frame.height, -1).astype(np.float32),
                       v.reshape(frame.height, -1).astype(np.float32), cv2.INTER_LINEAR,
                       borderMode=cv2.BORDER_WRAP)
    diff = np.abs(warped.astype(np.int16) - frame.images["C"].astype(np.int16)).max(axis=2)[seen]
    assert np.median(diff) <= 5, f"median |C - warped {other}| = {np.median(diff)} levels"
    # the comparison is not vacuous: an unrelated image differs a lot
    shifted = np.roll(warped, frame.width // 4, axis=1)
    diff_shift = np.abs(shifted.astype(np.int16) - frame.images["C"].astype(np.int16)).max(axis=2)[seen]
    assert np.median(diff_shift) > 3 * max(np.median(diff), 1)


# ------------------------------------------------------------------------------------------ textures


def _plane_points(n=200, spacing=0.01, z=1.0):
    """A 2 m x 2 m patch of the plane z = const sampled every ``spacing`` metres: (n*n, 3)."""
    g = np.arange(n) * spacing
    x, y = np.meshgrid(g, g)
    return np.stack([x.ravel(), y.ravel(), np.full(x.size, z)], axis=1)


@pytest.mark.parametrize("kind", sorted(set(TEXTURES) | {"fabric", "metal"}))
def test_textures_are_rich_and_contrast_zero_is_flat(kind):
    q = _plane_points()
    pts = SurfacePoints(q=q, face_axis=np.full(len(q), 2))
    m = Material(f"m_{kind}", kind=kind, color=(0.6, 0.5, 0.4), color2=(0.2, 0.2, 0.3), scale=0.3,
                 contrast=0.6)
    a = albedo(m, pts).mean(axis=1).reshape(200, 200)
    assert a.dtype == np.float32 and np.all(a >= 0)
    # texture at the scale of a few pixels (1-4 cm): the gradient must not vanish on most of the surface
    grad = np.hypot(np.diff(a, axis=1)[1:], np.diff(a, axis=0)[:, 1:])  # per cm
    min_grad = 0.0005 if kind == "board" else 0.002
    assert np.median(grad) > min_grad, f"{kind}: median |gradient| {np.median(grad):.2g} per cm"
    flat = albedo(Material(f"f_{kind}", kind=kind, color=(0.6, 0.5, 0.4), contrast=0.0), pts)
    assert np.all(flat == np.float32([0.6, 0.5, 0.4]))
    # deterministic, and seeded by the material name
    np.testing.assert_array_equal(albedo(m, pts), albedo(m, pts))
    other = Material(f"other_{kind}", kind=kind, color=(0.6, 0.5, 0.4), color2=(0.2, 0.2, 0.3), scale=0.3,
                     contrast=0.6)
    assert not np.array_equal(albedo(other, pts), albedo(m, pts))


def test_value_noise_is_continuous_bounded_and_seeded():
    rng = np.random.default_rng(0)
    q = rng.uniform(-20, 20, (5000, 3))
    n = value_noise(q, 7)
    assert n.min() >= 0 and n.max() < 1 and 0.45 < n.mean() < 0.55
    assert np.max(np.abs(value_noise(q + 1e-7, 7) - n)) < 1e-5   # continuous (also across lattice cells)
    assert np.mean(np.abs(value_noise(q, 8) - n)) > 0.1           # another seed, another field
    f = fbm(q, 7, 5)
    assert np.all(np.abs(f) <= 1) and 0.3 < f.std() < 0.6


# ------------------------------------------------------------------------------------------ frames


def test_render_frame_shapes_provenance_and_determinism(box_frame):
    spec, rig, frame = box_frame
    h, w = frame.height, frame.width
    assert (w, h) == (160, 80)
    for name in CAMERA_NAMES:
        assert frame.images[name].shape == (h, w, 3) and frame.images[name].dtype == np.uint8
        assert frame.distance[name].shape == (h, w) and frame.distance[name].dtype == np.float32
        assert np.all(np.isfinite(frame.distance[name]))  # a closed room: every ray hits
        assert frame.images[name].std() > 10  # textured, not a flat image
    r = frame.renderer
    assert r["renderer"] == "raycast" and r["engine"] == ENGINE and r["settings"]["supersample"] == 2
    assert r["versions"]["tri360"] == harness.__version__ and r["details"]["ambient"] == AMBIENT
    assert r["seconds"]["total"] > 0 and r["settings"]["width"] == 160
    again = render_frame(spec, rig, 160, "synthetic_box", "vp1", supersample=2)
    for name in CAMERA_NAMES:
        np.testing.assert_array_equal(again.images[name], frame.images[name])
        np.testing.assert_array_equal(again.distance[name], frame.distance[name])


def test_nothing_hit_is_infinite_and_background_coloured():
    spec = SceneSpec(name="open", background=(0.0, 0.0, 0.0))
    spec.add_material(Material("solid", contrast=0.0))
    spec.boxes.append(Box(center=(0.0, 3.0, 1.0), size=(1.0, 1.0, 1.0), material="solid"))
    image, dist = render_camera(spec, (0.0, 0.0, 1.0), np.eye(3), 64, supersample=1)
    assert np.isinf(dist).mean() > 0.9 and np.isfinite(dist[16, 32])  # the box straight ahead
    assert np.all(image[np.isinf(dist)] == 0)


def test_supersampling_antialiases_colour_but_not_distance():
    spec = room_spec(Box(center=(2.0, 0.0, 1.2), size=(0.5, 0.5, 0.5), material="solid"))
    img1, d1 = render_camera(spec, (0.0, 0.0, 1.2), np.eye(3), 64, supersample=1)
    img3, d3 = render_camera(spec, (0.0, 0.0, 1.2), np.eye(3), 64, supersample=3)
    np.testing.assert_array_equal(d1, d3)       # distance: pixel-centre ray only
    assert not np.array_equal(img1, img3)       # colour: averaged sub-pixel rays
    assert np.median(np.abs(img1.astype(int) - img3.astype(int))) < 20


def test_write_read_round_trip(box_frame, tmp_path):
    _, _, frame = box_frame
    out = write_frame(frame, tmp_path)
    back = read_frame(out)
    assert back.scene == "synthetic_box" and back.viewpoint == "vp1"
    assert back.renderer["engine"] == ENGINE
    for name in CAMERA_NAMES:
        np.testing.assert_array_equal(back.images[name], frame.images[name])
        np.testing.assert_array_equal(back.distance[name], frame.distance[name])
        np.testing.assert_allclose(back.cameras[name].position, frame.cameras[name].position, atol=1e-12)


# ------------------------------------------------------------------------------------------ scene


@pytest.mark.parametrize("preset", ["default", "small", "cluttered"])
def test_synthetic_box_presets_build_and_have_free_viewpoints(preset):
    entry, _ = get_scene(f"synthetic_box:{preset}")
    assert entry.renderer == "raycast"
    spec = entry.spec(preset, seed=0)
    solids = [b for b in spec.boxes if not b.inward]
    furniture = [b for b in solids if b.name not in ("floor", "board")]
    assert 3 <= len(furniture) <= 6 and len(spec.lights) in (1, 2)
    assert any(m.contrast == 0 for m in spec.materials.values())  # a weak-texture region exists
    rigs = choose_viewpoints(spec, 3, seed=0)
    assert len(rigs) == 3
    # furniture stays inside the room
    shell = next(b for b in spec.boxes if b.inward)
    for b in furniture:
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * b.size / 2
        world = corners @ yaw_rotation(b.yaw).T + b.center
        assert shell.contains(world).all(), b.name
    # the seed jitters the furniture
    other = entry.spec(preset, seed=1)
    assert [b.center for b in other.boxes] != [b.center for b in spec.boxes]
    assert [b.center for b in entry.spec(preset, seed=0).boxes] == [b.center for b in spec.boxes]


# ------------------------------------------------------------------------------------ cylinders and spheres


def _round_spec() -> SceneSpec:
    spec = room_spec()
    spec.cylinders.append(Cylinder((1.5, 1.0, 0.5), radius=0.4, length=1.0, material="solid", name="table"))
    spec.cylinders.append(Cylinder((-1.0, 1.5, 2.0), radius=0.1, length=2.0, material="solid", axis="x", yaw=0.7))
    spec.spheres.append(Sphere((-1.5, -1.0, 1.0), radius=0.5, material="solid", name="ball"))
    return spec


def test_round_shapes_exact_hits_on_known_rays():
    spec = _round_spec()
    o = np.array([0.0, 1.0, 0.5])
    # straight at the table's side; straight down onto its top; at the ball's centre
    t, idx, face, pts = raycast(spec, o, np.array([[1.0, 0.0, 0.0]]))
    assert idx[0] == 1 and face[0] == 0 and abs(t[0] - 1.1) < 1e-12
    t, idx, face, _ = raycast(spec, np.array([1.6, 1.1, 2.5]), np.array([[0.0, 0.0, -1.0]]))
    assert idx[0] == 1 and face[0] == 2 and abs(t[0] - 1.5) < 1e-12
    d = np.array([-1.5, -1.0, 1.0]) - o
    t, idx, face, _ = raycast(spec, o, (d / np.linalg.norm(d))[None])
    assert idx[0] == 3 and face[0] == 0 and abs(t[0] - (np.linalg.norm(d) - 0.5)) < 1e-12


def test_round_shape_hits_lie_on_the_surface_with_nothing_in_front():
    spec = _round_spec()
    o = np.array([0.1, -0.2, 1.3])
    dirs = bearing_grid(96, 48, yaw_rotation(0.3)).reshape(-1, 3)
    t, idx, face, pts = raycast(spec, o, dirs)
    assert np.isfinite(t).all()
    cyl, pipe, ball = spec.cylinders[0], spec.cylinders[1], spec.spheres[0]
    assert {1, 2, 3} <= set(idx.tolist())
    for k, shape in ((1, cyl), (2, pipe)):
        local = (pts[idx == k] - shape.center) @ shape.frame()
        radial, axial = np.hypot(local[:, 0], local[:, 1]), np.abs(local[:, 2])
        on_side = np.abs(radial - shape.radius) < 1e-12
        on_cap = (np.abs(axial - shape.length / 2) < 1e-12) & (radial <= shape.radius + 1e-12)
        assert np.all(on_side | on_cap) and np.array_equal(on_side & ~on_cap, face[idx == k] == 0)
    assert np.allclose(np.linalg.norm(pts[idx == 3] - ball.center, axis=1), ball.radius, atol=1e-12)
    # march along every ray up to 1 mm before its hit: never inside a round shape
    for s in np.linspace(0.02, 0.999, 40):
        p = o + (s * t - 1e-3 * (s == 0.999))[:, None] * dirs
        assert not any(shape.contains(p).any() for shape in (cyl, pipe, ball))


def test_round_shapes_are_shaded_and_glass_on_them_is_refused():
    spec = _round_spec()
    image, distance = render_camera(spec, (0.0, 0.0, 1.3), np.eye(3), 64)
    assert np.isfinite(distance).all() and image.mean() > 5
    spec.add_material(Material("pane", kind="glass"))
    spec.spheres.append(Sphere((0.0, -1.5, 1.0), 0.2, "pane"))
    assert "pane" in RaycastRenderer.unsupported(spec)
