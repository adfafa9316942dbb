"""The render job and the renderer registry without Blender: the ray-caster renders, settings are compared on a
rerun, bad input fails with one line naming the culprit, and nothing is left half-written."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys

import numpy as np
import pytest

import harness.commands.render as job
from harness.cli import build_parser, main
from harness.commands.render import MIN_WIDTH, differences, max_width
from harness.data.errors import UserError
from harness.data.frame import read_frame
from harness.render.base import BaseRenderer, Renderer, RenderSettings, identity, srgb_encode
from harness.render.raycast import RaycastRenderer
from harness.render.registry import RENDERER_CLASSES, available_renderers, get_renderer, open_renderer
from harness.runtime.context import QUIET
from reconstruction.camera.rig import Rig
from scenes.model import Box, Material, ModelFile, SceneParams, SceneSpec, param
from scenes.registry import SceneEntry, SceneError, discover
from tests.helpers import render_scene

W = 64  # >= MIN_WIDTH, tiny
FAST = {"width": W, "ctx": QUIET, "renderer": "raycast"}


def test_min_width_is_the_measured_flow_minimum():
    assert MIN_WIDTH == 60 and W >= MIN_WIDTH


def test_registry_lists_both_backends_with_one_interface():
    assert available_renderers() == ["cycles", "raycast"]
    for name, cls in RENDERER_CLASSES.items():
        assert cls.name == name and issubclass(cls, BaseRenderer)
        assert "width" in cls.pixel_settings and set(cls.pixel_settings) <= set(RenderSettings.__dataclass_fields__)
    with pytest.raises(UserError, match="unknown renderer 'nope' \\(known: cycles, raycast\\)"):
        get_renderer("nope")


def test_every_default_has_one_source():
    """The CLI's and the job's defaults are RenderSettings' (the shared dataclass), not copies."""
    args = build_parser().parse_args(["render"])
    d = RenderSettings()
    assert (args.width, args.samples, args.seed, args.threads, args.max_bounces, not args.no_denoise,
            args.light_tree) == (d.width, d.samples, d.seed, d.threads, d.max_bounces, d.denoise,
                                 d.light_tree) == (1000, 20, 0, 0, 4, True, False)
    assert build_parser().parse_args(["render", "--light-tree"]).light_tree is True
    assert not hasattr(args, "renderer"), "no --renderer means: the scene's default"


def test_srgb_encode_hand_values():
    lin = np.array([0.0, 0.0031308, 0.2140, 0.5, 1.0, 1.5, -0.1, np.nan])
    # IEC 61966-2-1 by hand: 0.0031308 -> 12.92 x = 0.04045 (x 255 = 10.31); 0.214 -> 0.49994 (127.48);
    # 0.5 -> 0.73536 (187.51)
    assert srgb_encode(lin).tolist() == [0, 10, 127, 188, 255, 255, 0, 0]
    assert srgb_encode(np.zeros((2, 3, 3))).shape == (2, 3, 3)


def test_raycast_frame_provenance_layout(tmp_path):
    (d,) = render_scene("synthetic_box", out_root=tmp_path, **FAST)
    r = read_frame(d).renderer
    assert r["renderer"] == "raycast" and r["engine"] == "tri360-raycast"
    assert set(r) == {"renderer", "engine", "versions", "settings", "pixel_settings", "scene", "rig", "details"}
    assert r["settings"] == {**vars(RenderSettings(width=W)), "width": W}
    assert r["pixel_settings"] == ["width", "supersample"]
    assert r["scene"]["family"] == "synthetic_box" and r["scene"]["preset"] == "default"
    assert r["scene"]["code_version"].startswith("sha256:") and r["scene"]["params"]["seed"] == 0
    seconds = json.loads((d / "render_log.json").read_text())["seconds"]  # timings: beside frame.json, not in it
    assert {"C", "U", "R", "build", "total"} <= set(seconds) and "tri360" in r["versions"]
    assert r["rig"]["baseline_m"] == 0.4


@pytest.mark.slow
def test_same_settings_skip_and_every_pixel_setting_is_compared(tmp_path):
    (d,) = render_scene("synthetic_box", out_root=tmp_path, **FAST)
    stamp = (d / "frame.json").stat().st_mtime_ns
    assert render_scene("synthetic_box", out_root=tmp_path, **FAST) == [d]
    assert (d / "frame.json").stat().st_mtime_ns == stamp, "a complete, identical frame was rendered again"
    cases = [({"width": W + 2}, f"width {W} \\(now {W + 2}\\)"),
             ({"baseline": 0.3}, "baseline_m 0.4 \\(now 0.3\\)"),
             ({"overrides": {"jitter_m": 0.1}}, "scene parameter jitter_m unset \\(now 0.1\\)"),
             ({"seed": 1}, "scene parameter seed 0 \\(now 1\\)")]
    for change, message in cases:
        with pytest.raises(UserError, match=f"{d}.*other settings.*{message}.*--force"):
            render_scene("synthetic_box", out_root=tmp_path, **{**FAST, **change})
    assert (d / "frame.json").stat().st_mtime_ns == stamp
    # the ray-caster's pixels do not depend on Cycles' settings: those are not compared for its frames
    assert render_scene("synthetic_box", out_root=tmp_path, samples=3, denoise=False, **FAST) == [d]
    # --force re-renders
    render_scene("synthetic_box", out_root=tmp_path, force=True, **{**FAST, "width": W + 2})
    assert read_frame(d).width == W + 2


def test_differences_cover_renderer_cycles_settings_code_version_and_poses(tmp_path):
    (d,) = render_scene("synthetic_box", out_root=tmp_path, **FAST)
    meta = json.loads((d / "frame.json").read_text())
    entry = discover()[0]["synthetic_box"]
    spec = entry.spec("default", 0)
    rig = Rig(position=np.asarray(meta["renderer"]["rig"]["position"]), yaw_rad=meta["renderer"]["rig"]["yaw_rad"])
    settings = RenderSettings(width=W)
    same = identity("raycast", RaycastRenderer.pixel_settings, settings, spec, 0.4)
    assert differences(meta, same, rig) == []
    assert differences(meta, same, Rig(position=rig.position + 0.01)) == [
        "camera poses (the viewpoint placement changed)"]
    spec.code_version = "sha256:0000"
    assert differences(meta, identity("raycast", RaycastRenderer.pixel_settings, settings, spec, 0.4), rig) == [
        f"scene code version {meta['renderer']['scene']['code_version']} (now sha256:0000)"]
    # as if Cycles had drawn it with 16 samples, no denoiser, 2 bounces, the light tree: a rerun with the defaults
    # names each
    cycles_settings = get_renderer("cycles").pixel_settings
    meta["renderer"] |= {"renderer": "cycles", "pixel_settings": list(cycles_settings),
                         "settings": {**meta["renderer"]["settings"], "samples": 16, "denoise": False,
                                      "max_bounces": 2, "light_tree": True}}
    spec.code_version = meta["renderer"]["scene"]["code_version"]
    diff = differences(meta, identity("cycles", cycles_settings, settings, spec, 0.4), rig)
    assert diff == ["samples 16 (now 20)", "denoise false (now true)", "max_bounces 2 (now 4)",
                    "light_tree true (now false)"]
    # a frame from before provenance recorded these: every missing item is a difference
    old = {**meta, "renderer": {"engine": "CYCLES", "samples": 12}}
    diff = differences(old, identity("cycles", cycles_settings, settings, spec, 0.4), rig)
    assert "renderer not recorded (now cycles)" in diff and "scene code version not recorded" in " ".join(diff)


def test_unknown_scene_parameter_is_named_with_the_known_ones(tmp_path):
    with pytest.raises(SceneError, match="^scene 'synthetic_box': rooom: expected one of the keys room, furniture, "
                                         "jitter_m, size_jitter, weak_contrast, light_power, got an unknown key$"):
        render_scene("synthetic_box", out_root=tmp_path, overrides={"rooom": [4, 4, 3]}, **FAST)
    with pytest.raises(SceneError, match="'seed' is not a scene parameter \\(use --seed\\)"):
        render_scene("synthetic_box", out_root=tmp_path, overrides={"seed": 3}, **FAST)
    assert not any(tmp_path.iterdir()), "nothing written"


def test_every_preset_key_is_declared():
    for name, entry in discover()[0].items():
        assert entry.parameters is not SceneParams and entry.known_parameters, f"{name} declares no parameters"
        for preset, params in entry.presets.items():
            assert set(params) <= set(entry.known_parameters), (name, preset)

    def build(params, seed):
        return SceneSpec(name="x")

    @dataclasses.dataclass(frozen=True)
    class Counts(SceneParams):
        n: int = param(1, "count")

    with pytest.raises(SceneError, match="^scene 'x': preset 'big': size: expected one of the keys n, got an unknown "):
        SceneEntry(name="x", build=build, presets={"default": {}, "big": {"size": 3}}, parameters=Counts)
    with pytest.raises(SceneError, match="renderer must be one of"):
        SceneEntry(name="x", build=build, renderer="blender")


def _model_spec(tmp_path) -> SceneSpec:
    obj = tmp_path / "cube.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    spec = SceneSpec(name="with_model", bounds=((-1, -1, 0), (1, 1, 2)))
    spec.add_material(Material("m"))
    spec.boxes.append(Box((0, 0, 1), (2, 2, 2), "m", inward=True))
    spec.models.append(ModelFile(path=obj))
    return spec


def test_raycast_refuses_model_files_and_glass(tmp_path):
    with pytest.raises(UserError, match="renderer 'raycast' cannot draw scene 'with_model': it places 1 external "
                                        "model file\\(s\\) .*cube.obj.* boxes only"):
        open_renderer("raycast", _model_spec(tmp_path), RenderSettings(width=W))
    spec = SceneSpec(name="glassy")
    spec.add_material(Material("pane", kind="glass"))
    spec.boxes.append(Box((0, 0, 1), (1, 1, 1), "pane"))
    assert "transparent glass" in RaycastRenderer.unsupported(spec)
    assert get_renderer("cycles").unsupported(spec) is None


def test_cli_raycast_refusal_is_one_line_and_writes_nothing(tmp_path, capsys):
    model = _model_spec(tmp_path).models[0].path
    out = tmp_path / "out"
    argv = ["render", "--scene", "classroom:small", "--renderer", "raycast", "--width", str(W), "--quiet",
            "--out", str(out), "--set", f"model_path={model}"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert err.startswith("tri360 render: error: renderer 'raycast' cannot draw scene 'classroom:small'")
    assert not out.exists()


@pytest.mark.slow
def test_classroom_renders_with_the_raycaster(tmp_path, capsys):
    """The --renderer flag overrides the scene's default (classroom is all boxes, so the ray-caster can draw it)."""
    assert main(["render", "--scene", "classroom:small", "--renderer", "raycast", "--width", str(W), "--quiet",
                 "--out", str(tmp_path)]) == 0
    (line,) = capsys.readouterr().out.splitlines()
    frame = read_frame(line)
    assert frame.renderer["renderer"] == "raycast" and frame.scene == "classroom-small"
    assert np.isfinite(frame.distance["C"]).all()


@pytest.mark.parametrize(("width", "message"), [
    (58, "--width must be >= 60, got 58: the reconstruction's flow backends fail on smaller images"),
    (61, "--width must be an even number"),
])
def test_width_below_the_flow_minimum_is_refused(width, message, tmp_path):
    with pytest.raises(UserError, match=message):
        render_scene("synthetic_box", out_root=tmp_path, **{**FAST, "width": width})


def test_width_above_memory_is_refused(monkeypatch, tmp_path):
    four_gib = 4 << 30
    top = max_width(four_gib)
    per_px = max(job.RECONSTRUCT_BYTES_PER_PIXEL, job.RENDER_BYTES_PER_PIXEL)
    usable = job.MEMORY_SHARE * four_gib
    assert job.BASE_BYTES + per_px * top * top / 2 <= usable < job.BASE_BYTES + per_px * (top + 2) ** 2 / 2
    assert 2000 < top < 3000  # 2.2 GiB at ~900 bytes per pixel: about 2450 px wide
    assert max_width() >= 1000, "the default width fits on this machine"
    monkeypatch.setattr(job, "physical_memory_bytes", lambda: four_gib)
    with pytest.raises(UserError, match=f"--width {top + 2} needs about .* GiB .* more than 80% of this machine's "
                                        f"4.0 GiB; use --width {top} or less"):
        render_scene("synthetic_box", out_root=tmp_path, **{**FAST, "width": top + 2})


def test_backends_satisfy_the_protocol():
    spec = discover()[0]["box_room"].spec("small", 0)
    with open_renderer("raycast", spec, RenderSettings(width=W)) as r:
        assert isinstance(r, Renderer)
        frame = r.render(Rig(position=np.array([0.0, 0.0, 1.2])), "box_room", "vp000")
    assert frame.width == W and frame.images["C"].shape == (W // 2, W, 3)


@pytest.mark.slow
def test_importing_the_render_layer_never_loads_bpy():
    code = ("import sys, harness.render.registry, harness.commands.render, harness.cli; harness.cli.build_parser(); "
            "print('bpy' in sys.modules, 'harness.render.cycles' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False False"
