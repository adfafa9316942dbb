"""The audit of the newer surfaces (plugins, ground truth, perturb, import, suites, validate_quality, robustness
studies), one section per command.

A failing case ends with exit status 2, exactly one line on stderr (``tri360 <command>: error: ...`` or the
job's :class:`harness.data.errors.UserError`) naming the culprit, no traceback, and nothing written or changed.
Frames are tiny ``synthetic_box`` frames ray-cast in numpy (``tests.helpers``).
"""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

import harness.commands.parts.suite
import harness.commands.perturb
import reconstruction.flow.backends
import reconstruction.plugins
import reconstruction.refine.lm
from harness.cli import main
from harness.commands.evaluate import evaluate, evaluate_task
from harness.commands.parts.suite import render_suite
from harness.commands.study import LIMIT_FRAMES
from harness.data.atomic import parse_staging_name
from harness.data.errors import UserError
from harness.data.exr import read_distance_exr
from harness.data.frame import write_frame
from harness.data.outputs import MARKER, check_output, mark_output, output_kind
from harness.data.predictions import write_method_info, write_prediction
from harness.runtime.cluster import ClusterOptions
from harness.runtime.context import QUIET, RunContext
from reconstruction.methods.base import MethodOutput
from reconstruction.methods.flow_pipeline import FlowMethod
from reconstruction.methods.registry import discover_methods, flow_methods, get_methods
from scenes.model import SceneEntry
from scenes.registry import discover, get_scene
from tests.helpers import make_synthetic_frame
from tools.research import validate_quality

# ----------------------------------------------------------------------------------------------- machinery


def run_cli(argv: list[str]) -> int:
    """``tri360 argv`` in-process -> exit status (argparse's own exit included)."""
    try:
        return main([str(a) for a in argv])
    except SystemExit as exc:
        return exc.code if isinstance(exc.code, int) else 1


def snapshot(root: Path) -> dict[str, tuple]:
    """Every entry under ``root``: directories by existence, files by (size, mtime)."""
    out = {}
    for p in sorted(root.rglob("*")):
        st = p.lstat()
        out[str(p.relative_to(root))] = ("dir",) if stat.S_ISDIR(st.st_mode) else ("file", st.st_size,
                                                                                  st.st_mtime_ns)
    return out


def staging_leftovers(root: Path) -> list[str]:
    return [str(p.relative_to(root)) for p in root.rglob(".*") if parse_staging_name(p.name) is not None]


def expect_refusal(argv: list, capfd, tree: Path, *culprits: str) -> str:
    """Run ``tri360 argv``: status 2, one error line naming every culprit, nothing under ``tree`` changed."""
    capfd.readouterr()
    before = snapshot(tree)
    code = run_cli(argv)
    out, err = capfd.readouterr()
    lines = [line for line in (out + err).splitlines() if line.strip()]
    assert code == 2, f"exit status {code}; output: {lines}"
    assert len(lines) == 1 and lines[0].startswith(f"tri360 {argv[0]}: error: "), lines
    for c in culprits:
        assert str(c) in lines[0], f"{c!r} not named in {lines[0]!r}"
    assert snapshot(tree) == before, "a refused command wrote or changed files"
    assert staging_leftovers(tree) == []
    return lines[0]


class FakeEntryPoint:
    """Stands in for an ``importlib.metadata.EntryPoint``."""

    def __init__(self, name: str, value: str, obj):
        self.name, self.value, self._obj = name, value, obj

    def load(self):
        return self._obj


def install_plugins(monkeypatch, group: str, *eps: FakeEntryPoint) -> None:
    monkeypatch.setattr(reconstruction.plugins, "entry_points",
                        lambda group=None, _g=group: list(eps) if group == _g else [])


class Peeker:
    """An outside method that tries every way to the answer: ``frame.distance``, then the distance files in
    ``frame.path``; it returns C's true distance if it finds it, else a constant 1 m."""

    def __init__(self, label: str = "peeker"):
        self.label = label

    def config(self) -> dict:
        return {"kind": "peeker"}

    def run(self, frame) -> MethodOutput:
        found = getattr(frame, "distance", {}).get("C")
        path = getattr(frame, "path", None)
        if found is None and path is not None and (Path(path) / "C.distance.exr").is_file():
            found = read_distance_exr(Path(path) / "C.distance.exr")
        if found is not None:
            return MethodOutput(np.asarray(found, np.float32).copy(), info={"saw_ground_truth": True})
        return MethodOutput(np.full((frame.height, frame.width), 1.0, np.float32))


class Scribbler(Peeker):
    """An outside method that overwrites the images it is handed (what is scored must not change)."""

    def run(self, frame) -> MethodOutput:
        for img in frame.images.values():
            img[...] = 0
        return super().run(frame)


class OracleImpostor(FlowMethod):
    """A plugin's subclass of the flow pipeline that calls its flow ``oracle`` to be handed ground truth."""


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    """A data root with one 64x32 synthetic_box frame."""
    r = tmp_path_factory.mktemp("audit") / "data"
    write_frame(make_synthetic_frame(64), r)
    return r


# ------------------------------------------------------------------------------------------------ evaluate


class TestEvaluateHidesGroundTruth:
    def test_an_outside_method_cannot_read_ground_truth_in_process(self, root, tmp_path):
        table = evaluate(root, tmp_path / "res", [Peeker(), *flow_methods(["oracle"], [True], ["average"])],
                         report=False, ctx=QUIET)
        mae = table.set_index("method").mae_m
        # a constant 1 m in a room of walls 1-4 m away: far from 0; the oracle still gets its ground truth
        assert mae["peeker"] > 0.3
        assert mae["oracle-rect:average"] < 0.05

    def test_the_task_a_dask_worker_runs_hides_it_too(self, root, tmp_path):
        (tmp_path / "stage").mkdir()
        frame = str(root / "synthetic_box" / "vp000")
        rows = evaluate_task(frame, [Peeker()], str(tmp_path / "stage"))["rows"]
        assert rows["peeker"][0]["mae_m"] > 0.3

    def test_a_method_overwriting_its_images_does_not_change_what_is_scored(self, root, tmp_path):
        honest = evaluate(root, tmp_path / "a", [Peeker()], report=False, ctx=QUIET)
        scribbled = evaluate(root, tmp_path / "b", [Scribbler()], report=False, ctx=QUIET)
        cols = ["mae_m", "rmse_m", "valid_px"]
        assert honest[cols].to_dict("records") == scribbled[cols].to_dict("records")
        regions_a = (tmp_path / "a" / "regions.csv").read_text()
        assert regions_a.replace("peeker", "x") == (tmp_path / "b" / "regions.csv").read_text().replace("peeker", "x")

    def test_a_subclass_calling_its_flow_oracle_is_not_handed_ground_truth(self, root, tmp_path, capfd):
        impostor = OracleImpostor("oracle")
        with pytest.raises(Exception, match="needs ground-truth distance"):
            evaluate(root, tmp_path / "res", [impostor], report=False, ctx=QUIET)

    def test_reconstruct_hides_it_as_well(self, root, tmp_path, monkeypatch):
        install_plugins(monkeypatch, "tri360.methods", FakeEntryPoint("peek", "peek_pkg:M", Peeker()))
        assert run_cli(["reconstruct", root / "synthetic_box" / "vp000", "--method", "peeker", "--out",
                        tmp_path / "preds", "--quiet"]) == 0
        info = json.loads((tmp_path / "preds/synthetic_box/vp000/reconstruction.json").read_text())
        assert info["info"] == {} and info["metrics"]["mae_m"] > 0.3

    def test_an_outside_method_plugin_cannot_read_it_through_the_command(self, root, tmp_path, monkeypatch):
        install_plugins(monkeypatch, "tri360.methods", FakeEntryPoint("peek", "peek_pkg:M", Peeker()))
        assert run_cli(["evaluate", root, "--method", "peeker", "--out", tmp_path / "res", "--no-report",
                        "--quiet"]) == 0
        row = (tmp_path / "res" / "results.csv").read_text().splitlines()
        header, values = row[0].split(","), row[1].split(",")
        assert float(values[header.index("mae_m")]) > 0.3


@pytest.mark.cluster
def test_evaluate_on_dask_workers_hides_ground_truth(root, tmp_path, dask_cluster):
    table = evaluate(root, tmp_path / "res", [Peeker()], report=False,
                     ctx=RunContext(ClusterOptions(scheduler=dask_cluster.address), progress=False))
    assert table.set_index("method").mae_m["peeker"] > 0.3


# ------------------------------------------------------------------------------------------------- plugins


class TestPluginsCannotShadow:
    def test_a_method_plugin_with_a_built_in_label_is_refused_and_named(self, monkeypatch):
        install_plugins(monkeypatch, "tri360.methods", FakeEntryPoint("evil", "evil_pkg:M", Peeker("fused-mirror")))
        methods, errors = discover_methods()
        assert not isinstance(methods["fused-mirror"], Peeker)
        (source, message), = errors.items()
        assert "evil_pkg:M" in source and "fused-mirror" in message and "refused" in message
        with pytest.raises(ValueError, match=r"evil_pkg:M.*refused"):
            get_methods(["fused-mirror"])

    def test_a_second_plugin_with_a_taken_label_is_refused(self, monkeypatch):
        install_plugins(monkeypatch, "tri360.methods", FakeEntryPoint("a", "a_pkg:M", Peeker("mine")),
                        FakeEntryPoint("b", "b_pkg:M", Peeker("mine")))
        reg = reconstruction.plugins.collect_registry([], "tri360.methods", lambda m: True, "Method",
                                                      key=lambda m: m.label)
        assert reg.sources == {"mine": "entry point a (a_pkg:M)"}
        assert reg.refused == {"mine": ("entry point b (b_pkg:M)", "entry point a (a_pkg:M)")}
        with pytest.raises(ValueError, match=r"b_pkg:M.*a_pkg:M"):
            get_methods(["mine"])

    def test_an_unknown_label_lists_each_outside_method_with_its_plugin(self, monkeypatch):
        install_plugins(monkeypatch, "tri360.methods", FakeEntryPoint("peek", "peek_pkg:M", Peeker()))
        with pytest.raises(ValueError, match=r"peeker \(entry point peek \(peek_pkg:M\)\)"):
            get_methods(["nonesuch"])

    def test_the_command_refuses_the_shadowed_label_in_one_line(self, root, tmp_path, monkeypatch, capfd):
        install_plugins(monkeypatch, "tri360.methods", FakeEntryPoint("evil", "evil_pkg:M", Peeker("fused-mirror")))
        expect_refusal(["reconstruct", root / "synthetic_box" / "vp000", "--out", tmp_path / "preds"], capfd,
                       tmp_path, "fused-mirror", "evil_pkg:M")

    def test_a_flow_or_variant_plugin_named_like_a_built_in_is_refused_when_asked_for(self, monkeypatch):
        dis = reconstruction.flow.backends.get_flow("dis")
        install_plugins(monkeypatch, "tri360.flows", FakeEntryPoint("f", "f_pkg:DIS", dataclasses.replace(dis)))
        assert reconstruction.flow.backends.discover_flows()[0]["dis"] is not None
        with pytest.raises(ValueError, match=r"flow 'dis'.*f_pkg:DIS.*refused") as info:
            reconstruction.flow.backends.get_flow("dis")
        assert "\n" not in str(info.value)
        with pytest.raises(ValueError, match=r"f_pkg:DIS"):
            flow_methods(["dis"], [True], ["average"])
        gradient = reconstruction.refine.lm.get_variant("gradient")
        install_plugins(monkeypatch, "tri360.variants", FakeEntryPoint("v", "v_pkg:G", dataclasses.replace(gradient)))
        with pytest.raises(ValueError, match=r"variant 'gradient'.*v_pkg:G"):
            reconstruction.refine.lm.get_variant("gradient")
        with pytest.raises(ValueError, match=r"v_pkg:G"):
            flow_methods(["dis"], [True], ["gradient"])

    def test_a_scene_plugin_named_like_a_built_in_is_refused(self, monkeypatch, capfd, tmp_path):
        corridor = get_scene("corridor")[0]
        fake = SceneEntry(**{**corridor.__dict__, "description": "not the built-in", "source": ""})
        install_plugins(monkeypatch, "tri360.scenes", FakeEntryPoint("c", "c_pkg:SCENES", fake))
        entries, errors = discover()
        assert entries["corridor"].description == corridor.description
        assert any("c_pkg:SCENES" in k and "corridor" in v for k, v in errors.items())
        with pytest.raises(Exception, match=r"c_pkg:SCENES"):
            get_scene("corridor")
        expect_refusal(["render", "--scene", "corridor", "--width", "64", "--renderer", "raycast", "--out",
                        tmp_path / "r"], capfd, tmp_path, "corridor", "c_pkg:SCENES")


# --------------------------------------------------------------------------------------------------- score


class TestScoreLabels:
    @pytest.fixture()
    def preds(self, root, tmp_path):
        p = tmp_path / "preds"
        write_prediction(p, "synthetic_box", "vp000", np.full((32, 64), 2.0, np.float32))
        write_method_info(p, {"name": "mine", "description": "a constant"})
        return p

    def test_a_built_in_label_contradicting_method_json_is_refused(self, root, preds, tmp_path, capfd):
        expect_refusal(["score", preds, "--data", root, "--method", "fused", "--out", tmp_path / "res"], capfd,
                       tmp_path, "--method fused", str(preds / "method.json"), "'mine'")

    def test_another_name_is_used_and_recorded_beside_method_json(self, root, preds, tmp_path):
        assert run_cli(["score", preds, "--data", root, "--method", "renamed", "--out", tmp_path / "res",
                        "--no-report", "--quiet"]) == 0
        cfg = json.loads((tmp_path / "res" / "config.json").read_text())["methods"]["renamed"]
        assert cfg["label_source"] == "--method" and cfg["method.json"]["name"] == "mine"


# ------------------------------------------------------------------------- output kinds (validate_quality, study)


def robustness_dir(path: Path, legacy: bool = False) -> Path:
    """A finished robustness study as ``study`` writes it (``legacy``: marked ``study``, as before the kinds split)."""
    (path / "data" / "none-0").mkdir(parents=True)
    (path / "results" / "none-0").mkdir(parents=True)
    (path / "points.json").write_text(json.dumps([{"kind": "none", "level": 0, "data": "data/none-0",
                                                   "results": "results/none-0"}]))
    (path / "robustness.csv").write_text("kind,level\nnone,0\n")
    (path / "robustness.md").write_text("# study\n")
    mark_output(path, "robustness")
    if legacy:
        raw = json.loads((path / MARKER).read_text())
        (path / MARKER).write_text(json.dumps({**raw, "kind": "study"}))
    return path


def grid_dir(path: Path) -> Path:
    """A finished grid study, marked as the study command marks it."""
    (path / "data").mkdir(parents=True)
    (path / "points.json").write_text(json.dumps([{"rid": "r0", "eid": "e0"}]))
    (path / "study.csv").write_text("width\n64\n")
    mark_output(path, "study")
    return path


class TestOutputKinds:
    @pytest.mark.parametrize("legacy", [False, True], ids=["marked", "marked-before-the-split"])
    def test_validate_quality_never_replaces_a_robustness_study(self, root, tmp_path, capfd, legacy):
        study = robustness_dir(tmp_path / "study", legacy)
        before = snapshot(tmp_path)
        capfd.readouterr()
        code = validate_quality.main([str(root), "--method", "sweep", "--out", str(study), "--quiet"])
        _, err = capfd.readouterr()
        assert code == 2 and len(err.strip().splitlines()) == 1, err
        assert str(study) in err and "robustness study" in err
        assert snapshot(tmp_path) == before

    def test_a_grid_study_is_not_accepted_into_a_robustness_study(self, tmp_path):
        study = robustness_dir(tmp_path / "study", legacy=True)
        with pytest.raises(UserError, match="robustness study"):
            check_output(study, "study")
        assert check_output(study, "robustness") == study

    def test_a_robustness_study_is_not_accepted_into_a_grid_study(self, tmp_path):
        grid = grid_dir(tmp_path / "grid")
        assert output_kind(grid) == "study"
        with pytest.raises(UserError, match="grid study"):
            check_output(grid, "robustness")

    def test_a_validation_is_its_own_kind(self, tmp_path):
        v = tmp_path / "v"
        v.mkdir()
        (v / "validation.json").write_text("{}")
        (v / "validation.md").write_text("x\n")
        assert output_kind(v) == "validation"
        assert check_output(v, "validation") == v
        for kind in ("study", "robustness", "results"):
            with pytest.raises(UserError, match="quality validation"):
                check_output(v, kind)


# ------------------------------------------------------------------------------ import (and every image reader)

RIG = Path(__file__).resolve().parents[1] / "examples" / "rig_paper_L_0.4m.json"


@pytest.fixture(scope="module")
def jpegs(tmp_path_factory):
    """C, U and R of a 128x64 synthetic_box frame as JPEG files."""
    tmp = tmp_path_factory.mktemp("jpg")
    frame = make_synthetic_frame(128)
    out = {}
    for n in "CUR":
        ok, buf = cv2.imencode(".jpg", cv2.cvtColor(frame.images[n], cv2.COLOR_RGB2BGR),
                               [cv2.IMWRITE_JPEG_QUALITY, 95])
        out[n] = tmp / f"{n}.jpg"
        out[n].write_bytes(buf.tobytes())
    return out


def copy_images(jpegs, where: Path) -> list[Path]:
    where.mkdir(parents=True, exist_ok=True)
    paths = []
    for n in "CUR":
        (where / f"{n}.jpg").write_bytes(jpegs[n].read_bytes())
        paths.append(where / f"{n}.jpg")
    return paths


class TestImport:
    def test_a_jpeg_with_200_bytes_overwritten_mid_file_is_refused(self, jpegs, tmp_path, capfd):
        c, u, r = copy_images(jpegs, tmp_path / "in")
        raw = bytearray(c.read_bytes())
        mid = len(raw) // 2
        raw[mid:mid + 200] = np.random.default_rng(0).integers(0, 256, 200, dtype=np.uint8).tobytes()
        c.write_bytes(bytes(raw))
        expect_refusal(["import", c, u, r, "--rig", RIG, "--out", tmp_path / "d" / "s" / "v"], capfd, tmp_path,
                       str(c), "corrupt JPEG")

    def test_a_truncated_jpeg_is_refused(self, jpegs, tmp_path, capfd):
        c, u, r = copy_images(jpegs, tmp_path / "in")
        c.write_bytes(c.read_bytes()[: c.stat().st_size * 2 // 3])
        expect_refusal(["import", c, u, r, "--rig", RIG, "--out", tmp_path / "d" / "s" / "v"], capfd, tmp_path,
                       str(c), "corrupt JPEG")

    def test_a_tiny_png_claiming_60000_by_30000_pixels_is_refused_before_decoding(self, jpegs, tmp_path, capfd):
        c, u, r = copy_images(jpegs, tmp_path / "in")
        png = bytearray(cv2.imencode(".png", np.zeros((32, 64, 3), np.uint8))[1].tobytes())
        png[16:24] = (60000).to_bytes(4, "big") + (30000).to_bytes(4, "big")
        huge = tmp_path / "in" / "huge.png"
        huge.write_bytes(bytes(png[:429]))
        expect_refusal(["import", huge, u, r, "--rig", RIG, "--out", tmp_path / "d" / "s" / "v"], capfd, tmp_path,
                       str(huge), "60000x30000")

    def test_a_width_beyond_this_machine_is_refused(self, jpegs, tmp_path, capfd):
        c, u, r = copy_images(jpegs, tmp_path / "in")
        expect_refusal(["import", c, u, r, "--rig", RIG, "--out", tmp_path / "d" / "s" / "v", "--width", "2000000"],
                       capfd, tmp_path, "--width 2000000")

    def test_images_of_different_sizes_are_refused_even_with_width(self, jpegs, tmp_path, capfd):
        c, u, r = copy_images(jpegs, tmp_path / "in")
        small = cv2.resize(cv2.imread(str(u)), (96, 48))
        cv2.imwrite(str(u), small)
        expect_refusal(["import", c, u, r, "--rig", RIG, "--out", tmp_path / "d" / "s" / "v", "--width", "64"],
                       capfd, tmp_path, "differ in size", str(u))

    @pytest.mark.parametrize("r_position", [[0.0, 0.0, -0.4], [0.02, 0.0, -0.4], [0.0, 0.0, 0.4]],
                             ids=["colinear-L", "near-colinear", "same-direction"])
    def test_a_colinear_rig_is_refused(self, jpegs, tmp_path, capfd, r_position):
        c, u, r = copy_images(jpegs, tmp_path / "in")
        rig = json.loads(RIG.read_text())
        rig["cameras"]["R"]["position"] = r_position
        if r_position == [0.0, 0.0, 0.4]:
            rig["cameras"]["U"]["position"] = [0.0, 0.0, 0.2]
            rig["baseline_m"] = 0.3
        bad = tmp_path / "in" / "rig.json"
        bad.write_text(json.dumps(rig))
        line = expect_refusal(["import", c, u, r, "--rig", bad, "--out", tmp_path / "d" / "s" / "v"], capfd,
                              tmp_path, str(bad), "colinear")
        assert "Traceback" not in line


class TestImageReading:
    def test_every_command_reading_a_frame_refuses_an_oversized_png_header(self, root, tmp_path, capfd):
        data = tmp_path / "data"
        write_frame(make_synthetic_frame(64), data)
        png = bytearray((data / "synthetic_box/vp000/U.png").read_bytes())
        png[16:24] = (60000).to_bytes(4, "big") + (30000).to_bytes(4, "big")
        (data / "synthetic_box/vp000/U.png").write_bytes(bytes(png))
        expect_refusal(["evaluate", data, "--out", tmp_path / "res", "--method", "sweep"], capfd, tmp_path,
                       str(data / "synthetic_box/vp000/U.png"), "60000x30000")
        expect_refusal(["reconstruct", data / "synthetic_box/vp000", "--out", tmp_path / "p", "--method", "sweep"],
                       capfd, tmp_path, "U.png", "60000x30000")

    def test_a_png_with_a_broken_chunk_is_refused(self, tmp_path, capfd):
        data = tmp_path / "data"
        write_frame(make_synthetic_frame(64), data)
        p = data / "synthetic_box/vp000/C.png"
        raw = bytearray(p.read_bytes())
        raw[len(raw) // 2:len(raw) // 2 + 40] = bytes(40)
        p.write_bytes(bytes(raw))
        expect_refusal(["evaluate", data, "--out", tmp_path / "res", "--method", "sweep"], capfd, tmp_path,
                       str(p), "corrupt PNG")


# ---------------------------------------------------------------------------------------------------- perturb


class TestPerturb:
    def test_two_frame_directories_naming_one_frame_are_refused(self, tmp_path, capfd):
        data = tmp_path / "data"
        src = write_frame(make_synthetic_frame(64), data)
        twin = data / "elsewhere" / "vp000"
        twin.parent.mkdir()
        twin.mkdir()
        for f in src.iterdir():
            (twin / f.name).write_bytes(f.read_bytes())
        expect_refusal(["perturb", data, "--out", tmp_path / "out", "--apply", "noise=2"], capfd, tmp_path,
                       "vp000", "frame.json")

    def test_an_interrupt_while_replacing_a_perturbed_root_leaves_the_previous_one_whole(self, tmp_path,
                                                                                         monkeypatch):
        data = tmp_path / "data"
        write_frame(make_synthetic_frame(64), data)
        write_frame(make_synthetic_frame(64, viewpoint=1), data)
        out = tmp_path / "out"
        assert run_cli(["perturb", data, "--out", out, "--apply", "noise=2"]) == 0
        before = snapshot(out)
        calls = []
        real = harness.commands.perturb.write_frame

        def interrupted(frame, root):
            calls.append(frame.viewpoint)
            if len(calls) == 2:
                raise KeyboardInterrupt
            return real(frame, root)

        monkeypatch.setattr(harness.commands.perturb, "write_frame", interrupted)
        assert run_cli(["perturb", data, "--out", out, "--apply", "noise=4"]) == 130
        assert calls == ["vp000", "vp001"]
        assert snapshot(out) == before and staging_leftovers(tmp_path) == []


# ------------------------------------------------------------------------------- argument errors (every command)


class TestArgumentErrors:
    @pytest.mark.parametrize("argv, culprit", [
        (["render", "--bogus"], "--bogus"),
        (["render", "--viewpoints", "two"], "--viewpoints"),
        (["evaluate", "--split", "train"], "--split"),
        (["score"], "required"),
        (["perturb", "data", "--out", "o", "--nonsense", "1"], "--nonsense"),
    ])
    def test_an_argument_error_is_one_line_naming_the_command_and_help(self, argv, culprit, capfd, tmp_path):
        line = expect_refusal(argv, capfd, tmp_path, culprit, f"`tri360 {argv[0]} --help`")
        assert "usage:" not in line

    def test_no_command_is_one_line_too(self, capfd):
        capfd.readouterr()
        assert run_cli([]) == 2
        out, err = capfd.readouterr()
        assert out == "" and err.strip().splitlines() == [
            "tri360: error: the following arguments are required: COMMAND (see `tri360 --help`)"]


# ------------------------------------------------------------------------------------------- render --suite

SUITE = """\
format = "tri360-suite/1"
name = "audit"

[render]
width = 64

[[frames]]
family = "synthetic_box"
seed = 11
viewpoints = {viewpoints}
split = "dev"
"""


def suite_file(where: Path, viewpoints: int) -> Path:
    path = where / f"audit{viewpoints}.toml"
    path.write_text(SUITE.format(viewpoints=viewpoints), encoding="utf-8")
    return path


def dead_pid() -> int:
    """The pid of a process that has exited (a run killed with kill -9)."""
    proc = subprocess.Popen([sys.executable, "-c", ""])
    proc.wait()
    return proc.pid


def plant_partials(directory: Path, name: str) -> tuple[Path, Path]:
    """A hidden staging directory of ``name`` in ``directory`` left by a dead process, and one of this (live)
    process; returns both."""
    directory.mkdir(parents=True, exist_ok=True)
    dead = directory / f".{name}.partial-{dead_pid()}-0badf00d"
    live = directory / f".{name}.partial-{os.getpid()}-12345678"
    for d in (dead, live):
        d.mkdir()
        (d / "frame.json").write_text("{", encoding="utf-8")
    return dead, live


def no_plan(*args, **kwargs):
    raise AssertionError("plan() built the scenes before the cheap check")


class TestRenderSuite:
    def test_more_than_100_frames_need_yes_before_any_scene_is_built(self, tmp_path, capfd, monkeypatch):
        big = suite_file(tmp_path, LIMIT_FRAMES + 1)
        monkeypatch.setattr(harness.commands.parts.suite, "plan", no_plan)
        line = expect_refusal(["render", "--suite", big, "--split", "dev", "--out", tmp_path / "data"], capfd,
                              tmp_path, str(big), f"{LIMIT_FRAMES + 1} frame(s)", f"more than {LIMIT_FRAMES}",
                              "--yes")
        assert "split dev" in line and not (tmp_path / "data").exists()

    def test_with_yes_it_goes_on_to_plan(self, tmp_path, monkeypatch):
        big = suite_file(tmp_path, LIMIT_FRAMES + 1)
        planned = []
        monkeypatch.setattr(harness.commands.parts.suite, "plan",
                            lambda *a, **k: planned.append(a) or (_ for _ in ()).throw(UserError("stop here")))
        assert run_cli(["render", "--suite", big, "--split", "dev", "--out", tmp_path / "data", "--yes"]) == 2
        assert len(planned) == 1

    def test_frames_already_complete_do_not_count(self, tmp_path):
        small = suite_file(tmp_path, 2)
        monkeypatch = pytest.MonkeyPatch()
        with monkeypatch.context() as m:
            m.setattr(harness.commands.parts.suite, "LIMIT_FRAMES", 1)
            with pytest.raises(UserError, match="2 frame"):
                render_suite(small, "dev", tmp_path / "data", ctx=QUIET)
            m.setattr(harness.commands.parts.suite, "LIMIT_FRAMES", 2)
            render_suite(small, "dev", tmp_path / "data", ctx=QUIET)
            m.setattr(harness.commands.parts.suite, "LIMIT_FRAMES", 0)
            assert len(render_suite(small, "dev", tmp_path / "data", ctx=QUIET)) == 2  # nothing left to do
            with pytest.raises(UserError, match="2 frame"):
                render_suite(small, "dev", tmp_path / "data", ctx=QUIET, force=True)

    def test_a_rerun_removes_the_partials_of_a_killed_run(self, tmp_path):
        small = suite_file(tmp_path, 2)
        data = tmp_path / "data"
        assert run_cli(["render", "--suite", small, "--split", "dev", "--out", data, "--quiet"]) == 0
        in_scene = plant_partials(data / "synthetic_box-s11", "vp001")
        at_root = plant_partials(data, "synthetic_box-s11")
        assert run_cli(["render", "--suite", small, "--split", "dev", "--out", data, "--quiet"]) == 0
        assert not in_scene[0].exists() and not at_root[0].exists()
        assert in_scene[1].exists() and at_root[1].exists()  # a live process's are left alone


# --------------------------------------------------------------------------------- evaluate / score --suite


@pytest.fixture(scope="module")
def suite_root(tmp_path_factory):
    """A two-frame suite file and a data root holding exactly its dev split."""
    tmp = tmp_path_factory.mktemp("auditsuite")
    path = suite_file(tmp, 2)
    render_suite(path, "dev", tmp / "data", ctx=QUIET)
    return path, tmp / "data"


class TestSuiteDataCheck:
    @pytest.mark.parametrize("command", ["evaluate", "score"])
    def test_a_missing_frame_is_named_before_any_scene_is_built(self, suite_root, tmp_path, capfd, monkeypatch,
                                                                command):
        data = tmp_path / "data"
        shutil.copytree(suite_root[1], data)
        shutil.rmtree(data / "synthetic_box-s11" / "vp001")
        monkeypatch.setattr(harness.commands.parts.suite, "plan", no_plan)
        argv = ([command, data] if command == "evaluate" else [command, tmp_path, "--data", data])
        expect_refusal([*argv, "--suite", suite_root[0], "--split", "dev", "--out", tmp_path / "res"], capfd,
                       tmp_path, "synthetic_box-s11/vp001 of suite audit (split dev) is missing")

    def test_an_extra_frame_is_named_before_any_scene_is_built(self, suite_root, tmp_path, capfd, monkeypatch):
        data = tmp_path / "data"
        shutil.copytree(suite_root[1], data)
        write_frame(make_synthetic_frame(64), data)
        monkeypatch.setattr(harness.commands.parts.suite, "plan", no_plan)
        expect_refusal(["evaluate", data, "--suite", suite_root[0], "--split", "dev", "--out", tmp_path / "res"],
                       capfd, tmp_path, "synthetic_box/vp000 is not in suite audit split dev")


# ------------------------------------------------------------- partials of killed evaluate / score / perturb


class TestRerunRemovesPartials:
    def test_evaluate(self, root, tmp_path):
        dead, live = plant_partials(tmp_path, "res")
        assert run_cli(["evaluate", root, "--out", tmp_path / "res", "--method", "dis-rect:average", "--no-report",
                        "--quiet"]) == 0
        assert not dead.exists() and live.exists()

    def test_score(self, root, tmp_path):
        preds = tmp_path / "preds"
        write_prediction(preds, "synthetic_box", "vp000", np.full((32, 64), 2.0, np.float32))
        dead, live = plant_partials(tmp_path, "res")
        assert run_cli(["score", preds, "--data", root, "--out", tmp_path / "res", "--no-report", "--quiet"]) == 0
        assert not dead.exists() and live.exists()

    def test_perturb(self, root, tmp_path):
        dead, live = plant_partials(tmp_path, "out")
        assert run_cli(["perturb", root, "--out", tmp_path / "out", "--apply", "noise=2"]) == 0
        assert not dead.exists() and live.exists()
