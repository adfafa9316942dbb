"""Real Cycles renders (tiny) of every Cycles scene, checked against independent geometry.

Tests marked ``blender`` render through the Cycles worker process (which alone imports bpy); the CLI-error and
import tests do not.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys

import numpy as np
import pytest

import harness.render.cycles_renderer
from harness.cli import main
from harness.data.errors import UserError
from harness.data.frame import find_frames, read_frame
from harness.render.base import RenderSettings
from harness.render.registry import open_renderer
from harness.runtime.context import QUIET
from reconstruction.camera.equirect import bearing_grid
from reconstruction.camera.rig import Rig
from reconstruction.plugins import Registry
from scenes.families.box_room import box_interior_distance
from scenes.model import Box, Material, ModelFile, SceneSpec, choose_viewpoints
from scenes.registry import SceneEntry, discover
from tests.helpers import cross_camera_consistency, render_scene

ENTRIES, _ = discover()
CYCLES_SCENES = sorted(n for n, e in ENTRIES.items() if e.renderer == "cycles")
FAST = {"samples": 2, "threads": 2, "ctx": QUIET}
TINY = RenderSettings(width=64, samples=1, threads=2, denoise=False)


def _marker_scene(marker_center, yaw=0.0) -> tuple[SceneSpec, Rig]:
    spec = SceneSpec(name="marker", bounds=((-3, -3, 0), (3, 3, 3)))
    spec.add_material(Material("walls", kind="paint", color=(0.2, 0.2, 0.2), contrast=0.0))
    spec.add_material(Material("marker", kind="emission", color=(1.0, 0.0, 0.0), contrast=0.0, emission=2.0))
    spec.boxes.append(Box((0, 0, 1.5), (6, 6, 3), "walls", inward=True))
    spec.boxes.append(Box(marker_center, (0.3, 0.3, 0.3), "marker"))
    return spec, Rig(position=np.array([0.0, 0.0, 1.5]), yaw_rad=yaw)


@pytest.mark.blender
@pytest.mark.parametrize("name", CYCLES_SCENES)
def test_every_cycles_scene_renders_a_valid_frame(name, tmp_path):
    (d,) = render_scene(name, viewpoints=1, out_root=tmp_path, width=64, **FAST)
    frame = read_frame(d)
    assert frame.width == 64 and frame.height == 32 and frame.has_ground_truth
    for cam in "CUR":
        img, dist = frame.images[cam], frame.distance[cam]
        assert img.dtype == np.uint8 and 10 < img.mean() < 250, f"{cam} image is black or blown out"
        assert np.isfinite(dist).all() and dist.min() > 0.05, "closed rooms: every ray hits something"
    r = frame.renderer
    assert r["renderer"] == "cycles" and r["engine"] == "CYCLES"
    assert r["settings"]["samples"] == 2 and r["settings"]["threads"] == 2 and r["settings"]["seed"] == 0
    assert r["details"]["threads"] == 2 and r["details"]["denoiser"] == "OPENIMAGEDENOISE"
    seconds = json.loads((frame.path / "render_log.json").read_text())["seconds"]  # timings: beside frame.json
    assert {"C", "U", "R", "build", "total"} <= set(seconds) and r["versions"]["blender"].startswith("5.")
    assert r["scene"]["family"] == name and r["scene"]["code_version"] == ENTRIES[name].code_version
    assert "tri360" in r["versions"] and "samples" in r["pixel_settings"]


@pytest.mark.blender
def test_box_room_distance_matches_closed_form(tmp_path):
    spec = ENTRIES["box_room"].spec(seed=0)
    rig = choose_viewpoints(spec, 2, seed=3)[1]  # off-centre, rotated rig
    assert abs(rig.yaw_rad) > 0.1
    with open_renderer("cycles", spec, RenderSettings(width=200, samples=1, threads=2, denoise=False)) as r:
        frame = r.render(rig, "box_room", "vp001")
    lo, hi = spec.bounds
    for cam, pose in frame.cameras.items():
        gt = box_interior_distance(pose.position, bearing_grid(200, 100, pose.rotation), lo, hi)
        err = np.abs(frame.distance[cam].astype(np.float64) - gt)
        assert np.median(err) < 1e-4, f"{cam}: median |err| {np.median(err):.2e} m"
        assert np.quantile(err, 0.999) < 1e-3, f"{cam}: 99.9 % |err| {np.quantile(err, 0.999):.2e} m"


@pytest.mark.blender
@pytest.mark.parametrize(("yaw", "marker", "where"), [
    (0.0, (2.0, 0.0, 1.5), "right"),      # +X world = camera right -> u = 0.75 W
    (0.0, (0.0, 2.0, 1.5), "forward"),    # +Y world = forward -> u = 0.5 W
    (0.0, (0.0, 0.0, 2.8), "up"),         # straight up -> top rows
    (np.pi / 2, (0.0, 2.0, 1.5), "right"),  # rig turned 90 deg left: its right is world +Y
])
def test_camera_convention(yaw, marker, where):
    spec, rig = _marker_scene(marker, yaw)
    with open_renderer("cycles", spec, TINY) as r:
        frame = r.render(rig, "marker", "vp000")
    img = frame.images["C"].astype(int)
    red = (img[..., 0] > 150) & (img[..., 1] < 60)
    assert red.sum() >= 2
    v, u = np.nonzero(red)
    if where == "up":
        assert v.max() <= 3, "the top rows look up"
    else:
        expect = {"right": 0.75, "forward": 0.5}[where] * 64
        assert abs(u.mean() + 0.5 - expect) < 1.5 and abs(v.mean() + 0.5 - 16) < 1.5


def _cross_check(f, k):
    """Project C's ground truth into camera k -> (agree within 2 %, occluded in k, |grey diff| /255)."""
    return cross_camera_consistency(f, k)


@pytest.mark.blender
def test_cross_camera_consistency(tmp_path):
    """Project C's ground-truth points into U and R: their own ground truth and colour must agree.

    box_room has no occlusion, so agreement must be (nearly) total.  In the classroom, points hidden from
    U or R by a nearer surface (0.4 m parallax around desks and chairs) are the only disagreement, and with
    the rig standing in an aisle they stay under 5 % (measured at 1000x500: 96-99 %); the classroom is
    rendered at 512 wide because at 256 the depth edges' share of pixels alone costs ~2 %.
    """
    (box,) = render_scene("box_room", out_root=tmp_path, width=256, samples=1, threads=2, denoise=False,
                           ctx=QUIET)
    (cls,) = render_scene("classroom", out_root=tmp_path, width=512, samples=8, threads=2, ctx=QUIET)
    fb, fc = read_frame(box), read_frame(cls)
    for k in "UR":
        agree, _, _ = _cross_check(fb, k)
        assert agree.mean() >= 0.995, f"box_room {k}: only {agree.mean():.2%} agree within 2 %"
        agree, occluded, diff = _cross_check(fc, k)
        assert (agree | occluded).mean() >= 0.95, f"classroom {k}: {(agree | occluded).mean():.1%} consistent"
        # the issue's own criterion: >= 95 % of C's pixels agree within 2 % (viewpoints stand in aisles)
        assert agree.mean() >= 0.95, f"classroom {k}: only {agree.mean():.1%} agree within 2 %"
        assert np.median(diff) < 4.0, f"classroom {k}: median colour diff {np.median(diff):.2f}/255"


@pytest.mark.blender
def test_same_seed_same_pixels(tmp_path):
    a = render_scene("box_room", out_root=tmp_path / "a", width=64, samples=4, threads=2, seed=5, ctx=QUIET)
    b = render_scene("box_room", out_root=tmp_path / "b", width=64, samples=4, threads=2, seed=5, ctx=QUIET)
    c = render_scene("box_room", out_root=tmp_path / "c", width=64, samples=4, threads=2, seed=6, ctx=QUIET)
    fa, fb, fc = (read_frame(x[0]) for x in (a, b, c))
    for cam in "CUR":
        assert np.array_equal(fa.images[cam], fb.images[cam])
        assert np.array_equal(fa.distance[cam], fb.distance[cam])
    assert any(not np.array_equal(fa.images[k], fc.images[k]) for k in "CUR")


@pytest.mark.blender
def test_resume_compares_settings_and_interrupted_render_leaves_nothing(tmp_path, monkeypatch):
    opts = dict(viewpoints=2, out_root=tmp_path, width=64, **FAST)
    first = render_scene("box_room", **opts)
    stamps = [(p / "frame.json").stat().st_mtime_ns for p in first]

    def boom(*a, **k):
        raise AssertionError("a complete frame was rendered again")

    monkeypatch.setattr(harness.render.cycles_renderer.CyclesRenderer, "render_camera", boom)
    assert render_scene("box_room", **opts) == first
    assert [(p / "frame.json").stat().st_mtime_ns for p in first] == stamps
    # every setting that changes Cycles' pixels is compared (and named), none is silently kept
    for change, named in [({"width": 66}, "width 64 (now 66)"), ({"samples": 3}, "samples 2 (now 3)"),
                          ({"denoise": False}, "denoise true (now false)"),
                          ({"max_bounces": 2}, "max_bounces 4 (now 2)"),
                          ({"baseline": 0.3}, "baseline_m 0.4 (now 0.3)"),
                          ({"renderer": "raycast"}, "renderer cycles (now raycast)")]:
        with pytest.raises(UserError, match="other settings") as info:
            render_scene("box_room", **{**opts, **change})
        assert named in str(info.value) and str(first[0]) in str(info.value)
    monkeypatch.undo()

    # interrupt vp001 at its last camera: vp000 stays, vp001 and its hidden partial directory are gone
    real, calls = harness.render.cycles_renderer.CyclesRenderer.render_camera, []

    def interrupted(self, name, pose):
        calls.append(name)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(self, name, pose)

    monkeypatch.setattr(harness.render.cycles_renderer.CyclesRenderer, "render_camera", interrupted)
    shutil.rmtree(first[1])
    with pytest.raises(KeyboardInterrupt):
        render_scene("box_room", **opts)
    assert [p.name for p in (tmp_path / "box_room").iterdir()] == ["vp000"], "partial files left behind"
    monkeypatch.undo()
    render_scene("box_room", **opts)
    assert [p.name for p in find_frames(tmp_path)] == ["vp000", "vp001"]


@pytest.mark.blender
def test_model_file_obj_is_imported(tmp_path):
    obj = tmp_path / "cube.obj"
    v = [(x, y, z) for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)]
    faces = [(1, 2, 4, 3), (5, 7, 8, 6), (1, 5, 6, 2), (3, 4, 8, 7), (1, 3, 7, 5), (2, 6, 8, 4)]
    obj.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in v)
                   + "".join(f"f {a} {b} {c} {d}\n" for a, b, c, d in faces))
    spec, rig = _marker_scene((0.0, -2.5, 0.3))
    spec.models.append(ModelFile(path=obj, location=(2.0, 0.0, 1.5), scale=0.5))  # 0.5 m cube at +X, 2 m away
    with open_renderer("cycles", spec, TINY) as r:
        frame = r.render(rig, "marker", "vp000")
    assert abs(frame.distance["C"][16, 48] - 1.75) < 0.01  # front face at x = 2 - 0.25
    assert abs(frame.distance["C"][16, 16] - 3.0) < 0.01  # -X wall


@pytest.mark.slow
def test_importing_the_cli_does_not_load_bpy():
    code = "import sys, harness.cli, harness.commands.render; harness.cli.build_parser(); print('bpy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


@pytest.mark.parametrize(("argv", "message"), [
    (["--scene", "nope"], "unknown scene 'nope'"),
    (["--scene", "classroom:huge"], "unknown preset 'huge'"),
    (["--width", "63"], "--width must be an even number"),
    (["--width", "4"], "--width must be >= 60"),
    (["--width", "1000000"], "--width 1000000 needs about"),
    (["--set", "rowz=2"], "scene 'classroom': rowz: expected one of the keys size, rows, cols,"),
    (["--set", "rows=many"], "scene 'classroom': rows: expected an integer in [0, 100], got 'many'"),
    (["--samples", "0"], "--samples must be >= 1"),
    (["--viewpoints", "0"], "--viewpoints must be >= 1"),
    (["--threads", "-1"], "--threads must be >= 0"),
    (["--baseline", "-0.4"], "--baseline must be a positive"),
    (["--set", "novalue"], "--set expects KEY=VALUE"),
])
def test_cli_errors_are_one_line(argv, message, tmp_path, capsys):
    assert main(["render", "--out", str(tmp_path), "--quiet", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err and err.startswith("tri360 render: error:")


def test_cli_unwritable_output_and_failing_scene(tmp_path, capsys, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert main(["render", "--scene", "box_room", "--out", str(blocker / "sub"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "exists and is not a directory" in err

    def broken(params, seed):
        raise ZeroDivisionError("bad layout")

    fake = {"broken": SceneEntry(name="broken", build=broken, source="scenes/broken.py")}
    monkeypatch.setattr("scenes.registry.scene_registry", lambda: Registry(entries=fake))
    assert main(["render", "--scene", "broken", "--out", str(tmp_path), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "scene 'broken' (scenes/broken.py) failed to build" in err


def test_cli_scenes_lists_every_scene(capsys):
    assert main(["scenes"]) == 0
    out = capsys.readouterr().out
    for name, e in ENTRIES.items():
        assert name in out and f"[{e.renderer}]" in out


def test_cli_scenes_params_lists_each_field_with_unit_default_and_limits(capsys):
    assert main(["scenes", "--params"]) == 0
    out = capsys.readouterr().out
    assert "--set light_power=...: power per ceiling area light, W (default 35; >= 0)" in out
    assert "--set rows=...: student desk rows, along y (default 5; in [0, 100])" in out
    assert "--set furniture=...: furniture boxes, in order (default table, cabinet, cube, bench; each one of " in out
    for name, e in ENTRIES.items():
        for key in e.known_parameters:
            assert f"--set {key}=...: " in out, (name, key)
    assert "small: {'size': (6.0, 5.0, 2.7), 'rows': 3" in out  # a preset: its overrides

