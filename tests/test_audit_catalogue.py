"""The audit of the newer surfaces (plugins, ground truth, perturb, import, suites, validate_quality, robustness
studies), one section per command.

A failing case ends with exit status 2, exactly one line on stderr (``tri360 <command>: error: ...`` or the
job's :class:`harness.data.errors.UserError`) naming the culprit, no traceback, and nothing written or changed.
Frames are tiny ``synthetic_box`` frames ray-cast in numpy (``tests.helpers``).
"""

from __future__ import annotations

import dataclasses
import gc
import inspect
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
import harness.runtime.blind
import reconstruction.flow.backends
import reconstruction.methods.base
import reconstruction.plugins
import reconstruction.refine.lm
import tools.overview
import tools.presets_snapshot
import tools.regression
import tools.research.select_matching
import tools.research.select_photometric
import tools.scene_fingerprints
from harness.cli import main
from harness.commands.evaluate import evaluate, evaluate_task
from harness.commands.parts.captured import captured_twin
from harness.commands.parts.suite import render_suite
from harness.commands.study import LIMIT_FRAMES
from harness.data.atomic import parse_staging_name
from harness.data.errors import UserError
from harness.data.exr import read_distance_exr
from harness.data.frame import write_frame
from harness.data.outputs import MARKER, check_output, mark_output, output_kind
from harness.data.photometric import KEYS as PHOTOMETRIC_KEYS
from harness.data.photometric import CameraDistribution
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


def _expect_one_line(run, capfd, tree: Path, prefix: str, culprits) -> str:
    """``run()`` -> exit status 2, exactly one line starting with ``prefix`` and naming every culprit, nothing under
    ``tree`` changed, no staging directory left."""
    capfd.readouterr()
    before = snapshot(tree)
    code = run()
    out, err = capfd.readouterr()
    lines = [line for line in (out + err).splitlines() if line.strip()]
    assert code == 2, f"exit status {code}; output: {lines}"
    assert len(lines) == 1 and lines[0].startswith(prefix), lines
    for c in culprits:
        assert str(c) in lines[0], f"{c!r} not named in {lines[0]!r}"
    assert snapshot(tree) == before, "a refused command wrote or changed files"
    assert staging_leftovers(tree) == []
    return lines[0]


def expect_refusal(argv: list, capfd, tree: Path, *culprits: str) -> str:
    """Run ``tri360 argv``: status 2, one error line naming every culprit, nothing under ``tree`` changed."""
    return _expect_one_line(lambda: run_cli(argv), capfd, tree, f"tri360 {argv[0]}: error: ", culprits)


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
    """An outside method that makes its input writable and overwrites it: black images, U moved 5 cm up (what is
    scored, and what any other method sees, must not change)."""

    def run(self, frame) -> MethodOutput:
        for img in frame.images.values():
            img.setflags(write=True)  # its own copy: allowed, and harmless
            img[...] = 0
        position = frame.cameras["U"].position
        position.setflags(write=True)
        position[2] += 0.05
        return super().run(frame)


class Snoop(Peeker):
    """An outside method that looks everywhere for what a method must not see: the frame's ground truth, directory,
    provenance (a twin's true poses, the rig placement, the scene recipe, a perturbation's true cameras) and
    photometric records on its input; a path in ``sys.argv``; a frame in its callers' stack frames or anywhere in its
    process.  It writes what it found (a list of strings) as JSON to ``report`` and returns a constant 1 m."""

    SECRETS = ("distance", "path", "renderer", "photometric", "scene", "viewpoint", "has_ground_truth", "metadata")

    def __init__(self, report: Path, label: str = "snoop"):
        super().__init__(label)
        self.report = str(report)

    def run(self, frame) -> MethodOutput:
        found = [f"input.{name}" for name in self.SECRETS if hasattr(frame, name)]
        found += [f"argv {a}" for a in sys.argv[1:] if os.path.exists(a)]
        def holds_frame(v) -> bool:
            return hasattr(v, "renderer") or hasattr(v, "has_ground_truth") or (hasattr(v, "distance")
                                                                              and hasattr(v, "images"))
        for info in inspect.stack()[1:]:
            found += [f"stack {info.function}.{k}" for k, v in info.frame.f_locals.items() if holds_frame(v)]
        found += [f"gc {type(o).__name__}" for o in gc.get_objects() if type(o).__name__ in ("Frame", "FrameRef")]
        try:
            frame.cameras["U"] = frame.cameras["C"]
            found.append("cameras can be replaced")
        except TypeError:
            pass
        try:
            frame.images["C"][0, 0] = 0
            found.append("images are writable")
        except ValueError:
            pass
        Path(self.report).write_text(json.dumps(found))
        return MethodOutput(np.full((frame.height, frame.width), 1.0, np.float32))


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
    @pytest.mark.slow
    def test_an_outside_method_cannot_read_ground_truth_in_process(self, root, tmp_path):
        table = evaluate(root, tmp_path / "res", [Peeker(), *flow_methods(["oracle"], [True], ["average"])],
                         report=False, ctx=QUIET)
        mae = table.set_index("method").mae_m
        # a constant 1 m in a room of walls 1-4 m away: far from 0; the oracle still gets its ground truth
        assert mae["peeker"] > 0.3
        assert mae["oracle-rect:average"] < 0.05

    @pytest.mark.slow
    def test_the_task_a_dask_worker_runs_hides_it_too(self, root, tmp_path):
        (tmp_path / "stage").mkdir()
        frame = str(root / "synthetic_box" / "vp000")
        rows = evaluate_task(frame, [Peeker()], str(tmp_path / "stage"))["rows"]
        assert rows["peeker"][0]["mae_m"] > 0.3

    @pytest.mark.slow
    def test_a_method_overwriting_its_images_does_not_change_what_is_scored(self, root, tmp_path):
        honest = evaluate(root, tmp_path / "a", [Peeker()], report=False, ctx=QUIET)
        scribbled = evaluate(root, tmp_path / "b", [Scribbler()], report=False, ctx=QUIET)
        cols = ["mae_m", "rmse_m", "valid_px"]
        assert honest[cols].to_dict("records") == scribbled[cols].to_dict("records")
        regions_a = (tmp_path / "a" / "regions.csv").read_text()
        assert regions_a.replace("peeker", "x") == (tmp_path / "b" / "regions.csv").read_text().replace("peeker", "x")

    @pytest.mark.slow
    def test_a_method_editing_its_input_changes_no_other_methods_result(self, root, tmp_path):
        builtin = flow_methods(["dis"], [True], ["average"])
        alone = evaluate(root, tmp_path / "a", builtin, report=False, ctx=QUIET).set_index("method")
        beside = evaluate(root, tmp_path / "b", [Scribbler(), *builtin], report=False, ctx=QUIET).set_index("method")
        label = builtin[0].label
        # the same computation on the same images and poses: equal to float rounding (metres)
        np.testing.assert_allclose(beside.loc[label, ["mae_m", "rmse_m"]].to_numpy(float),
                                   alone.loc[label, ["mae_m", "rmse_m"]].to_numpy(float), rtol=1e-9, atol=1e-12)
        assert beside.loc[label, "valid_px"] == alone.loc[label, "valid_px"]

    @pytest.mark.slow
    def test_a_snooping_method_finds_nothing_in_evaluate(self, root, tmp_path):
        report = tmp_path / "found.json"
        evaluate(root, tmp_path / "res", [Snoop(report)], report=False, ctx=QUIET)
        assert json.loads(report.read_text()) == []

    @pytest.mark.slow
    def test_a_snooping_plugin_finds_nothing_through_the_commands(self, root, tmp_path, monkeypatch):
        install_plugins(monkeypatch, "tri360.methods", FakeEntryPoint("snoop", "snoop_pkg:M",
                                                                      Snoop(tmp_path / "found.json")))
        for argv in (["evaluate", root, "--method", "snoop", "--out", tmp_path / "res", "--no-report", "--quiet"],
                     ["reconstruct", root / "synthetic_box" / "vp000", "--method", "snoop", "--out", tmp_path / "p",
                      "--quiet"]):
            (tmp_path / "found.json").unlink(missing_ok=True)
            assert run_cli(argv) == 0
            assert json.loads((tmp_path / "found.json").read_text()) == [], argv[0]

    def test_a_builtin_method_is_handed_a_read_only_copy(self, root, tmp_path, monkeypatch):
        seen = []
        original = reconstruction.methods.base.run_methods

        def spy(frame, methods, on_stage=None):
            seen.append(frame)
            return original(frame, methods, on_stage=on_stage)
        monkeypatch.setattr(harness.runtime.blind, "run_methods", spy)
        evaluate(root, tmp_path / "res", flow_methods(["dis"], [True], ["average"]), report=False, ctx=QUIET)
        (inp,) = seen
        assert not any(hasattr(inp, name) for name in Snoop.SECRETS)
        assert not inp.images["C"].flags.writeable and not inp.cameras["U"].position.flags.writeable
        with pytest.raises(TypeError):
            inp.cameras["U"] = inp.cameras["C"]

    @pytest.mark.slow
    def test_a_subclass_calling_its_flow_oracle_is_not_handed_ground_truth(self, root, tmp_path, capfd):
        impostor = OracleImpostor("oracle")
        with pytest.raises(Exception, match="needs ground-truth distance"):
            evaluate(root, tmp_path / "res", [impostor], report=False, ctx=QUIET)

    @pytest.mark.slow
    def test_reconstruct_hides_it_as_well(self, root, tmp_path, monkeypatch):
        install_plugins(monkeypatch, "tri360.methods", FakeEntryPoint("peek", "peek_pkg:M", Peeker()))
        assert run_cli(["reconstruct", root / "synthetic_box" / "vp000", "--method", "peeker", "--out",
                        tmp_path / "preds", "--quiet"]) == 0
        info = json.loads((tmp_path / "preds/synthetic_box/vp000/reconstruction.json").read_text())
        assert info["info"] == {} and info["metrics"]["mae_m"] > 0.3

    @pytest.mark.slow
    def test_an_outside_method_plugin_cannot_read_it_through_the_command(self, root, tmp_path, monkeypatch):
        install_plugins(monkeypatch, "tri360.methods", FakeEntryPoint("peek", "peek_pkg:M", Peeker()))
        assert run_cli(["evaluate", root, "--method", "peeker", "--out", tmp_path / "res", "--no-report",
                        "--quiet"]) == 0
        row = (tmp_path / "res" / "results.csv").read_text().splitlines()
        header, values = row[0].split(","), row[1].split(",")
        assert float(values[header.index("mae_m")]) > 0.3


@pytest.mark.cluster
def test_evaluate_on_dask_workers_hides_ground_truth(root, tmp_path, dask_cluster):
    report = tmp_path / "found.json"
    table = evaluate(root, tmp_path / "res", [Peeker(), Snoop(report)], report=False,
                     ctx=RunContext(ClusterOptions(scheduler=dask_cluster.address), progress=False))
    assert table.set_index("method").mae_m["peeker"] > 0.3
    assert json.loads(report.read_text()) == []


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

    @pytest.mark.slow
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


class TestPerturbTwin:
    """``tri360 perturb`` of a captured twin (:func:`twin_root`, in the evaluate / score --suite section)."""

    @pytest.mark.parametrize("applies", [["rotation=0.5", "exposure=0.5"], ["translation=0.5"], ["noise=2"]])
    def test_it_keeps_the_photometric_records_and_records_the_true_poses(self, twin_root, tmp_path, applies):
        out = tmp_path / "out"
        argv = ["perturb", twin_root[1] / TWIN, "--out", out] + [a for x in applies for a in ("--apply", x)]
        assert run_cli(argv) == 0
        src = json.loads((twin_root[1] / TWIN / "frame.json").read_text(encoding="utf-8"))
        new = json.loads((out / TWIN / "frame.json").read_text(encoding="utf-8"))
        for k in "CUR":
            assert new["cameras"][k]["photometric"] == src["cameras"][k]["photometric"]
        condition, perturbation = new["renderer"]["condition"], new["renderer"]["perturbation"]
        assert condition == src["renderer"]["condition"]
        if "noise=2" not in applies:  # the images keep the true poses of the twin's source, not its told ones
            assert perturbation["true_cameras"] == condition["true_cameras"]
            assert perturbation["true_baseline_m"] == condition["true_baseline_m"]


# ------------------------------------------------------------------------------- argument errors (every command)


class TestArgumentErrors:
    @pytest.mark.parametrize("argv, culprit", [
        (["render", "--bogus"], "--bogus"),
        (["render", "--viewpoints", "two"], "--viewpoints"),
        (["evaluate", "--split", "val"], "--split"),
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

    @pytest.mark.slow
    def test_a_rerun_removes_the_partials_of_a_killed_run(self, tmp_path):
        small = suite_file(tmp_path, 2)
        data = tmp_path / "data"
        assert run_cli(["render", "--suite", small, "--split", "dev", "--out", data, "--quiet"]) == 0
        in_scene = plant_partials(data / "synthetic_box-s11", "vp001")
        at_root = plant_partials(data, "synthetic_box-s11")
        assert run_cli(["render", "--suite", small, "--split", "dev", "--out", data, "--quiet"]) == 0
        assert not in_scene[0].exists() and not at_root[0].exists()
        assert in_scene[1].exists() and at_root[1].exists()  # a live process's are left alone


def captured_suite_file(where: Path, translation_mm: str = "[1.0, 2.0]", groups: str = "") -> Path:
    """The one-viewpoint audit suite with a ``captured`` condition, ``groups`` more ``[[frames]]`` tables."""
    path = where / "captured.toml"
    path.write_text(SUITE.format(viewpoints=1) + groups + "\n[conditions.captured]\n"
                    f"translation_mm = {translation_mm}\n", encoding="utf-8")
    return path


class TestRenderSuiteConditions:
    def test_a_calibration_error_the_rig_cannot_take_is_refused_before_any_work(self, tmp_path, capfd,
                                                                                monkeypatch):
        path = captured_suite_file(tmp_path, "[900, 1000]")
        monkeypatch.setattr(harness.commands.parts.suite, "plan", no_plan)
        line = expect_refusal(["render", "--suite", path, "--split", "dev", "--out", tmp_path / "data"], capfd,
                              tmp_path, f"{path}: [conditions.captured] translation_mm: ", "up to 1000 mm",
                              "frames[0] (synthetic_box-s11, baseline 0.4 m)", "impossible rig", "below 4 mm")
        assert "frame.json" not in line and not (tmp_path / "data").exists()

    def test_a_group_named_like_a_twin_directory_is_refused(self, tmp_path, capfd, monkeypatch):
        path = captured_suite_file(tmp_path, groups='\n[[frames]]\nfamily = "synthetic_box"\nseed = 12\n'
                                                    'viewpoints = 1\nsplit = "dev"\n'
                                                    'name = "synthetic_box-s11.captured"\n')
        monkeypatch.setattr(harness.commands.parts.suite, "plan", no_plan)
        expect_refusal(["render", "--suite", path, "--split", "dev", "--out", tmp_path / "data"], capfd, tmp_path,
                       f"{path}: frames[1] name: 'synthetic_box-s11.captured'", "frames[0]'s captured twins")
        assert not (tmp_path / "data").exists()


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


@pytest.fixture(scope="module")
def twin_root(tmp_path_factory):
    """The captured audit suite file and a data root holding its dev split: one frame and its twin."""
    tmp = tmp_path_factory.mktemp("audittwins")
    path = captured_suite_file(tmp)
    render_suite(path, "dev", tmp / "data", ctx=QUIET)
    return path, tmp / "data"


TWIN = "synthetic_box-s11.captured/vp000"
TWIN_SOURCE = "synthetic_box-s11/vp000"
TAMPERED = [("told poses reset", "the told pose of U is its true pose, but the recorded calibration error of U"),
            ("photometric records dropped", "cameras.C has no photometric record"),
            ("source image changed", f"its source frame {TWIN_SOURCE} changed after the twin was derived")]


def tamper_twin(data: Path, how: str) -> None:
    """Change the twin of :func:`twin_root`'s data root, or its source image, in one of the ways of TAMPERED."""
    if how == "source image changed":
        png = data / TWIN_SOURCE / "C.png"
        img = cv2.imread(str(png))
        img[0, 0] = 255 - img[0, 0]
        cv2.imwrite(str(png), img)
        return
    meta_path = data / TWIN / "frame.json"
    meta = json.loads(meta_path.read_text(encoding="utf-8"))
    record = meta["renderer"]["condition"]
    for k in "CUR":
        if how == "told poses reset" and k != "C":
            meta["cameras"][k].update(record["true_cameras"][k])
        elif how == "photometric records dropped":
            del meta["cameras"][k]["photometric"]
    if how == "told poses reset":
        meta["baseline_m"] = record["true_baseline_m"]
    meta_path.write_text(json.dumps(meta), encoding="utf-8")


class TestSuiteTwinCheck:
    @pytest.mark.parametrize("command", ["evaluate", "score"])
    @pytest.mark.parametrize(("how", "culprit"), TAMPERED)
    def test_a_twin_that_does_not_match_its_derivation_is_refused(self, twin_root, tmp_path, capfd, command, how,
                                                                  culprit):
        data = tmp_path / "data"
        shutil.copytree(twin_root[1], data)
        tamper_twin(data, how)
        argv = ([command, data] if command == "evaluate" else [command, tmp_path, "--data", data])
        expect_refusal([*argv, "--suite", twin_root[0], "--split", "dev", "--out", tmp_path / "res"], capfd,
                       tmp_path, f"{data / TWIN / 'frame.json'}: twin {TWIN} does not match its derivation: ",
                       culprit, f"`tri360 render --suite {twin_root[0]} --split dev --out {data}`")

    @pytest.mark.parametrize("how", [how for how, _ in TAMPERED])
    def test_render_derives_such_a_twin_again_and_leaves_its_source_alone(self, twin_root, tmp_path, how):
        data = tmp_path / "data"
        shutil.copytree(twin_root[1], data)
        tamper_twin(data, how)
        source = snapshot(data / TWIN_SOURCE)
        assert run_cli(["render", "--suite", twin_root[0], "--split", "dev", "--out", data, "--quiet"]) == 0
        assert snapshot(data / TWIN_SOURCE) == source
        suite = harness.commands.parts.suite.load(twin_root[0])
        assert len(harness.commands.parts.suite.check_suite_data(suite, "dev", data)) == 2


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


# ------------------------------------------------------------------------------------------------ overview
# (python -m tools.overview RESULTS FRAME_DIR --out PNG)


def expect_tool_refusal(tool_main, argv: list, capfd, tree: Path, prog: str, *culprits: str) -> str:
    """Run a tool's ``main(argv)``: status 2, one line ``<prog>: ...`` naming every culprit, nothing under ``tree``
    changed."""
    def run() -> int:
        try:
            return tool_main([str(a) for a in argv])
        except SystemExit as exc:
            return exc.code
    return _expect_one_line(run, capfd, tree, f"{prog}: ", culprits)


OVERVIEW = "python -m tools.overview"


@pytest.fixture(scope="class")
def evaluated(tmp_path_factory):
    """``(a directory, the data root in it, its frame directory, a results set of method 'peeker' evaluated on it)``,
    shared by a class's tests (each uses names of its own in the directory)."""
    tmp = tmp_path_factory.mktemp("overview")
    data = tmp / "data"
    frame_dir = write_frame(make_synthetic_frame(64), data)
    res = tmp / "res"
    evaluate(data, res, [Peeker()], report=False, ctx=QUIET)
    return tmp, data, frame_dir, res


@pytest.mark.slow
class TestOverview:
    def test_results_csv_as_out_is_refused(self, evaluated, capfd):
        tmp, _, frame_dir, res = evaluated
        expect_tool_refusal(tools.overview.main, [res, frame_dir, "--method", "peeker", "--out", res / "results.csv"],
                            capfd, tmp, OVERVIEW, str(res / "results.csv"), "not an overview PNG")

    def test_an_input_image_of_the_frame_as_out_is_refused(self, evaluated, capfd):
        tmp, _, frame_dir, res = evaluated
        expect_tool_refusal(tools.overview.main, [res, frame_dir, "--method", "peeker", "--out", frame_dir / "C.png"],
                            capfd, tmp, OVERVIEW, str(frame_dir / "C.png"))

    def test_a_new_file_inside_the_results_set_or_the_data_root_is_refused(self, evaluated, capfd):
        tmp, data, frame_dir, res = evaluated
        for out in (res / "overview.png", data / "overview.png", frame_dir / "overview.png"):
            expect_tool_refusal(tools.overview.main, [res, frame_dir, "--method", "peeker", "--out", out], capfd,
                                tmp, OVERVIEW, str(out), "is inside")

    def test_an_existing_directory_as_out_is_one_line(self, evaluated, capfd):
        tmp, _, frame_dir, res = evaluated
        (tmp / "pics").mkdir()
        line = expect_tool_refusal(tools.overview.main, [res, frame_dir, "--method", "peeker", "--out", tmp / "pics"],
                                   capfd, tmp, OVERVIEW, str(tmp / "pics"), "is a directory")
        assert "Traceback" not in line

    def test_a_parent_that_is_a_file_or_absent_is_refused(self, evaluated, capfd):
        tmp, _, frame_dir, res = evaluated
        (tmp / "afile").write_text("x")
        expect_tool_refusal(tools.overview.main, [res, frame_dir, "--method", "peeker", "--out",
                                                  tmp / "afile" / "o.png"], capfd, tmp, OVERVIEW, "afile")
        expect_tool_refusal(tools.overview.main, [res, frame_dir, "--method", "peeker", "--out",
                                                  tmp / "nowhere" / "o.png"], capfd, tmp, OVERVIEW, "nowhere")

    def test_an_unwritable_parent_is_refused(self, evaluated, capfd):
        tmp, _, frame_dir, res = evaluated
        # /sys takes no new files, root's included (a chmod-ed folder would not stop root)
        expect_tool_refusal(tools.overview.main, [res, frame_dir, "--method", "peeker", "--out",
                                                  Path("/sys/o.png")], capfd, tmp, OVERVIEW, "not writable")

    def test_only_a_png_the_tool_wrote_is_replaced(self, evaluated, capfd):
        tmp, _, frame_dir, res = evaluated
        foreign = tmp / "foreign.png"
        foreign.write_bytes(cv2.imencode(".png", np.zeros((8, 16, 3), np.uint8))[1].tobytes())
        expect_tool_refusal(tools.overview.main, [res, frame_dir, "--method", "peeker", "--out", foreign], capfd,
                            tmp, OVERVIEW, str(foreign), "not an overview PNG")
        out = tmp / "overview.png"
        assert tools.overview.main([str(res), str(frame_dir), "--method", "peeker", "--out", str(out)]) == 0
        first = out.read_bytes()
        assert tools.overview.main([str(res), str(frame_dir), "--method", "peeker", "--out", str(out)]) == 0
        assert out.read_bytes() == first and staging_leftovers(tmp) == []

    def test_a_frame_of_another_data_root_with_the_same_names_is_refused(self, evaluated, capfd):
        tmp, _, frame_dir, res = evaluated
        other = write_frame(make_synthetic_frame(64), tmp / "other")
        assert (other.parent.name, other.name) == (frame_dir.parent.name, frame_dir.name)
        expect_tool_refusal(tools.overview.main, [res, other, "--method", "peeker", "--out", tmp / "o.png"], capfd,
                            tmp, OVERVIEW, str(other), str(frame_dir.resolve()))

    def test_a_results_set_without_frames_json_is_refused(self, evaluated, capfd):
        tmp, _, frame_dir, res = evaluated
        bare = tmp / "bare-res"
        shutil.copytree(res, bare)
        (bare / "frames.json").unlink()
        expect_tool_refusal(tools.overview.main, [bare, frame_dir, "--method", "peeker", "--out", tmp / "o.png"],
                            capfd, tmp, OVERVIEW, str(bare / "frames.json"))


# ---------------------------------------------------------------------------- research tools (argument errors)
# (tools/research/*.py, tools/regression.py, tools/overview.py, tools/scene_fingerprints.py, tools/presets_snapshot.py)


class TestResearchToolArguments:
    @pytest.mark.parametrize("tool, argv, culprit", [
        ("overview", ["res", "frame", "--bogus"], "--bogus"),
        ("overview", [], "required"),
        ("regression", ["--bounds", "b.json", "--margin", "wide"], "--margin"),
        ("regression", ["--bounds", "b.json", "--waive", "nonsense"], "--waive"),
        ("scene_fingerprints", ["--nope"], "--nope"),
        ("research.validate_quality", ["data"], "--method"),
        ("research.select_matching", ["data"], "--out"),
        ("research.select_photometric", ["data", "--out", "o", "--split", "train"], "--split"),
        ("presets_snapshot", ["--nope"], "--nope"),
    ])
    def test_an_argument_error_is_one_line_naming_the_tool_and_help(self, tool, argv, culprit, capfd, tmp_path):
        module = {"overview": tools.overview, "regression": tools.regression,
                  "scene_fingerprints": tools.scene_fingerprints, "presets_snapshot": tools.presets_snapshot,
                  "research.validate_quality": validate_quality,
                  "research.select_matching": tools.research.select_matching,
                  "research.select_photometric": tools.research.select_photometric}[tool]
        prog = f"python -m tools.{tool}"
        line = expect_tool_refusal(module.main, argv, capfd, tmp_path, f"{prog}: error", culprit,
                                   f"`{prog} --help`")
        assert "usage:" not in line


class TestToolFiles:
    """The files the maintenance tools read and write: a file that is not theirs is never replaced, a malformed one
    is one line; checked before any render."""

    @pytest.mark.parametrize("tool, flag", [(tools.regression, "--bounds"), (tools.scene_fingerprints, "--file"),
                                            (tools.presets_snapshot, "--file")])
    @pytest.mark.parametrize("target", ["README.md", "csv", "dir", "missing-folder/x.json"])
    def test_update_never_replaces_a_file_that_is_not_its_own(self, tool, flag, target, capfd, tmp_path):
        paths = {"README.md": tmp_path / "README.md", "csv": tmp_path / "results.csv", "dir": tmp_path / "d",
                 "missing-folder/x.json": tmp_path / "missing-folder" / "x.json"}
        (tmp_path / "README.md").write_text("# a project\n")
        (tmp_path / "results.csv").write_text("scene,mae_m\nx,0.1\n")
        (tmp_path / "d").mkdir()
        prog = f"python -m {tool.__name__}"
        argv = [flag, paths[target], "--update", *(["--force"] if tool is tools.scene_fingerprints else [])]
        expect_tool_refusal(tool.main, argv, capfd, tmp_path, prog, paths[target])

    @pytest.mark.parametrize("tool, flag", [(tools.regression, "--bounds"), (tools.scene_fingerprints, "--file"),
                                            (tools.presets_snapshot, "--file")])
    def test_a_file_that_is_not_its_own_is_one_line_when_checked(self, tool, flag, capfd, tmp_path):
        (tmp_path / "results.csv").write_text("scene,mae_m\nx,0.1\n")
        expect_tool_refusal(tool.main, [flag, tmp_path / "results.csv"], capfd, tmp_path,
                            f"python -m {tool.__name__}", tmp_path / "results.csv", "not")


# -------------------------------------------------------------------------------------------------- import
# (a rig file's photometric records)


def rig_with(where: Path, **photometric) -> Path:
    """The example rig with a ``photometric`` record for each camera given."""
    rig = json.loads(RIG.read_text())
    for name, record in photometric.items():
        rig["cameras"].setdefault(name, {})["photometric"] = record
    where.mkdir(parents=True, exist_ok=True)
    path = where / "rig.json"
    path.write_text(json.dumps(rig))
    return path


FULL_RECORD = {"exposure_stops": 0.3, "white_balance": [1.1, 1.0, 0.9], "vignetting": {"axis": "y", "edge_loss": 0.2},
               "noise": {"shot": 0.001, "read": 0.0001}, "response": "srgb", "jpeg_quality": 90, "seed": 7}


class TestImportPhotometric:
    def test_a_record_holding_nan_is_refused_naming_the_key(self, jpegs, tmp_path, capfd):
        c, u, r = copy_images(jpegs, tmp_path / "in")
        rig = rig_with(tmp_path / "in", U={**FULL_RECORD, "exposure_stops": float("nan")})
        assert "NaN" in rig.read_text()
        expect_refusal(["import", c, u, r, "--rig", rig, "--out", tmp_path / "d" / "s" / "v"], capfd, tmp_path,
                       str(rig), "cameras.U.photometric: exposure_stops: expected", "nan")

    def test_a_record_without_a_seed_is_refused_naming_the_key(self, jpegs, tmp_path, capfd):
        c, u, r = copy_images(jpegs, tmp_path / "in")
        rig = rig_with(tmp_path / "in", R={k: v for k, v in FULL_RECORD.items() if k != "seed"})
        expect_refusal(["import", c, u, r, "--rig", rig, "--out", tmp_path / "d" / "s" / "v"], capfd, tmp_path,
                       str(rig), "cameras.R.photometric", "seed")

    def test_valid_records_are_carried_into_frame_json(self, jpegs, tmp_path):
        c, u, r = copy_images(jpegs, tmp_path / "in")
        rig = rig_with(tmp_path / "in", C=FULL_RECORD, U={**FULL_RECORD, "seed": 8})
        out = tmp_path / "d" / "s" / "v"
        assert run_cli(["import", c, u, r, "--rig", rig, "--out", out]) == 0
        cams = json.loads((out / "frame.json").read_text())["cameras"]
        assert cams["C"]["photometric"] == FULL_RECORD and cams["U"]["photometric"]["seed"] == 8
        assert "photometric" not in cams["R"]

    @pytest.mark.parametrize("where, key", [((), "units"), (("cameras",), "L"), (("cameras", "C"), "position"),
                                            (("cameras", "U"), "focal")])
    def test_a_key_the_rig_file_does_not_hold_is_refused_not_ignored(self, jpegs, tmp_path, capfd, where, key):
        c, u, r = copy_images(jpegs, tmp_path / "in")
        rig = json.loads(RIG.read_text())
        node = rig
        for w in where:
            node = node.setdefault(w, {})
        node[key] = [0.0, 0.0, 0.1]
        path = tmp_path / "in" / "rig.json"
        path.write_text(json.dumps(rig))
        expect_refusal(["import", c, u, r, "--rig", path, "--out", tmp_path / "d" / "s" / "v"], capfd, tmp_path,
                       str(path), ".".join([*where, key]))


# ------------------------------------------------------------------------------------------------- methods
# (tri360 methods: plugin labels that cannot be selected)


class TestMethodsListing:
    def test_unusable_plugin_labels_are_warned_about_one_line_each_and_not_listed(self, monkeypatch, capfd):
        install_plugins(monkeypatch, "tri360.methods",
                        FakeEntryPoint("two", "two_pkg:M", [Peeker("sweep"), Peeker("fused-mirror")]),
                        FakeEntryPoint("spaced", "spaced_pkg:M", Peeker("my method")),
                        FakeEntryPoint("fine", "fine_pkg:M", Peeker("fine-one")))
        capfd.readouterr()
        assert run_cli(["methods"]) == 0
        out, err = capfd.readouterr()
        warnings = err.strip().splitlines()
        assert len(warnings) == 3, warnings
        assert all(w.startswith("warning: ") and "cannot be selected" in w for w in warnings)
        for label, source in (("'sweep'", "two_pkg:M"), ("'fused-mirror'", "two_pkg:M"),
                              ("'my method'", "spaced_pkg:M")):
            assert any(label in w and source in w for w in warnings), (label, warnings)
        plugins = out.split("plugins' methods")[1].splitlines()[1:]
        assert [ln.split()[0] for ln in plugins if ln.strip()] == ["fine-one"]

    def test_scenes_warns_about_every_refused_scene_of_a_plugin_and_lists_neither(self, monkeypatch, capfd):
        fakes = [SceneEntry(**{**get_scene(n)[0].__dict__, "description": "not the built-in", "source": ""})
                 for n in ("corridor", "office")]
        install_plugins(monkeypatch, "tri360.scenes", FakeEntryPoint("two", "two_pkg:SCENES", fakes))
        capfd.readouterr()
        assert run_cli(["scenes"]) == 0
        out, err = capfd.readouterr()
        warnings = err.strip().splitlines()
        assert len(warnings) == 2, warnings
        for name in ("'corridor'", "'office'"):
            assert any(name in w and "two_pkg:SCENES" in w and "cannot be selected" in w for w in warnings), warnings
        assert "not the built-in" not in out

    def test_every_refused_name_of_one_entry_point_is_reported(self, monkeypatch):
        install_plugins(monkeypatch, "tri360.methods",
                        FakeEntryPoint("two", "two_pkg:M", [Peeker("sweep"), Peeker("fused-mirror")]))
        methods, errors = discover_methods()
        (source, message), = errors.items()
        assert "two_pkg:M" in source and "'sweep'" in message and "'fused-mirror'" in message
        with pytest.raises(ValueError, match=r"two_pkg:M.*'sweep'.*'fused-mirror'"):
            get_methods(["sweep-nonesuch"])


# ------------------------------------------------------------------------------------- frame / photometric
# (a camera's photometric record in frame.json)


class TestFramePhotometric:
    @pytest.mark.slow
    def test_a_record_missing_a_key_is_refused_naming_file_camera_and_key(self, tmp_path, capfd):
        data = tmp_path / "data"
        d = write_frame(make_synthetic_frame(64), data)
        meta = json.loads((d / "frame.json").read_text())
        meta["cameras"]["U"]["photometric"] = {"noise": {"shot": 0.001, "read": 0.0001}}
        (d / "frame.json").write_text(json.dumps(meta))
        expect_refusal(["evaluate", data, "--out", tmp_path / "res", "--method", "sweep"], capfd, tmp_path,
                       str(d / "frame.json"), "cameras.U.photometric: exposure_stops:", "got nothing")
        expect_refusal(["reconstruct", d, "--out", tmp_path / "p", "--method", "sweep"], capfd, tmp_path,
                       "cameras.U.photometric", "exposure_stops")

    def test_what_tri360_writes_has_every_key(self, tmp_path):
        twin = captured_twin(make_synthetic_frame(64), CameraDistribution(), seed=3)
        d = write_frame(twin, tmp_path / "data")
        cams = json.loads((d / "frame.json").read_text())["cameras"]
        assert all(set(cams[n]["photometric"]) == set(PHOTOMETRIC_KEYS) for n in "CUR")
