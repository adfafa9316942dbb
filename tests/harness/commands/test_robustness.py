"""The robustness study (``tri360 study`` of a ``kind = "robustness"`` file): per kind and level the frames are
perturbed and evaluated, robustness.csv/md and a plot per kind are written, level 0 is the unperturbed frames'
evaluation, reruns reuse everything, bad files are one line; the doubling level's interpolation."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import harness.commands.parts.robustness as rob
from harness.cli import main
from harness.commands.evaluate import evaluate
from harness.commands.parts.perturbations import rotation_about
from harness.commands.parts.suite import load as load_suite
from harness.commands.perturb import perturb_frame
from harness.data.frame import validate_metadata, write_frame
from harness.runtime.context import QUIET
from reconstruction.camera.rig import CameraPose
from reconstruction.methods.registry import get_methods
from reports.robustness import doubling_level, kind_table, pooled_mae
from reports.tables import pixel_weighted
from tests.helpers import ROOT, make_synthetic_frame

PNG = b"\x89PNG\r\n\x1a\n"
METHOD = "dis-rect:average"
STUDY = """kind = "robustness"
data = "{data}"
method = ["{method}"]
seed = 3

[levels]
rotation = [1, 5]
noise = [2, 8]
"""


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    """A data root of two 128 px ray-cast frames (synthetic_box vp000, vp001)."""
    root = tmp_path_factory.mktemp("src")
    for vp in (0, 1):
        write_frame(make_synthetic_frame(width=128, viewpoint=vp), root)
    return root


@pytest.fixture(scope="module")
def study(source, tmp_path_factory):
    """The study file and its finished run (through the command line)."""
    d = tmp_path_factory.mktemp("study")
    path = d / "robustness.toml"
    path.write_text(STUDY.format(data=source, method=METHOD), encoding="utf-8")
    out = d / "out"
    assert main(["study", str(path), "--out", str(out), "--quiet"]) == 0
    return path, out


@pytest.mark.slow
def test_files_and_one_row_per_kind_level_method_frame(study):
    _, out = study
    for name in ("robustness.csv", "robustness.md", "points.json", ".tri360-output.json"):
        assert (out / name).is_file(), name
    for kind in ("rotation", "noise"):
        assert (out / f"{kind}.png").read_bytes().startswith(PNG)
    for name in ("unperturbed", "rotation-1", "rotation-5", "noise-2", "noise-8"):
        assert len(list((out / "data" / name).rglob("frame.json"))) == 2, name
        assert (out / "results" / name / "results.csv").is_file(), name
    table = pd.read_csv(out / "robustness.csv")
    assert list(table.columns[:8]) == ["kind", "level", "unit", "method", "frame", "mae_m", "median_m", "valid_px"]
    assert len(table) == (2 * 2 + 1) * 1 * 2  # (kinds x levels + level 0) x methods x frames
    assert not table.duplicated(["kind", "level", "method", "frame"]).any()
    assert sorted(table.frame.unique()) == ["synthetic_box/vp000", "synthetic_box/vp001"]
    assert set(zip(table.kind, table.level, strict=True)) == {("none", 0), ("rotation", 1), ("rotation", 5),
                                                              ("noise", 2), ("noise", 8)}
    assert set(table[table.kind == "rotation"].unit) == {"degrees"}
    md = (out / "robustness.md").read_text()
    assert "## rotation (degrees)" in md and "## noise (grey levels at mid-grey)" in md
    assert "rotation.png" in md and f"| {METHOD} |" in md


@pytest.mark.slow
def test_level_0_is_an_evaluate_of_the_unperturbed_frames(study, source, tmp_path):
    _, out = study
    ref = evaluate(source, tmp_path / "ref", get_methods([METHOD]), report=False, ctx=QUIET)
    table = pd.read_csv(out / "robustness.csv")
    zero = table[table.kind == "none"].sort_values("frame")
    ref = ref.sort_values("viewpoint")
    np.testing.assert_allclose(zero.mae_m.to_numpy(), ref.mae_m.to_numpy(float), rtol=0, atol=1e-9)
    pooled = pooled_mae(table)
    base = float(pooled[(pooled.kind == "none") & (pooled.method == METHOD)].mae_m.iloc[0])
    assert base == pytest.approx(pixel_weighted(ref.mae_m, ref.valid_px), abs=1e-9)
    md = (out / "robustness.md").read_text()
    assert f"| {METHOD} | {base:.4f} |" in md


@pytest.mark.slow
def test_several_degrees_of_rotation_error_raise_the_flow_methods_mae(study):
    _, out = study
    pooled = pooled_mae(pd.read_csv(out / "robustness.csv"))
    mae = {(k, lv): m for k, lv, m in zip(pooled.kind, pooled.level, pooled.mae_m, strict=True)}
    assert mae[("rotation", 5)] > 1.5 * mae[("none", 0)]


@pytest.mark.slow
def test_perturbed_frames_name_their_source_and_level(study, source):
    _, out = study
    (meta,) = (out / "data" / "rotation-5" / "synthetic_box" / "vp001").glob("frame.json")
    rec = json.loads(meta.read_text())["renderer"]["perturbation"]
    assert rec["source"]["path"] == str((source / "synthetic_box" / "vp001").resolve())
    assert [(a["kind"], a["level"]) for a in rec["applied"]] == [("rotation", 5.0)] and rec["seed"] == 3


@pytest.mark.slow
def test_rerun_reuses_every_frame_and_result(study, monkeypatch):
    path, out = study
    calls = []
    monkeypatch.setattr(rob, "perturb_frames", lambda *a, **k: calls.append(("perturb", a)))
    monkeypatch.setattr(rob, "evaluate", lambda *a, **k: calls.append(("evaluate", a)))
    before = {p: p.stat().st_mtime_ns for d in ("data", "results") for p in (out / d).rglob("*") if p.is_file()}
    assert len(before) > 20
    table = rob.run_robustness(path, out, ctx=QUIET)
    assert calls == []
    assert {p: p.stat().st_mtime_ns for p in before} == before
    pd.testing.assert_frame_equal(table.reset_index(drop=True),
                                  pd.read_csv(out / "robustness.csv").fillna({"unit": ""}), check_dtype=False)


@pytest.mark.slow
def test_an_added_level_runs_only_itself_and_a_new_seed_every_perturbed_point_but_not_level_0(source, tmp_path):
    p = tmp_path / "r.toml"
    p.write_text(STUDY.format(data=source, method=METHOD).replace("noise = [2, 8]\n", "").replace("[1, 5]", "[1]"))
    o = tmp_path / "o"
    rob.run_robustness(p, o, ctx=QUIET)
    first = {q: q.stat().st_mtime_ns for q in (o / "results").rglob("results.csv")}
    p.write_text(p.read_text().replace("[1]", "[1, 2]"))  # an added level: only that point runs
    rob.run_robustness(p, o, ctx=QUIET)
    added = {q: q.stat().st_mtime_ns for q in (o / "results").rglob("results.csv")}
    assert {q: t for q, t in added.items() if q in first} == first and o / "results" / "rotation-2" / \
        "results.csv" in added
    p.write_text(p.read_text().replace("seed = 3", "seed = 4"))
    rob.run_robustness(p, o, ctx=QUIET)
    second = {q: q.stat().st_mtime_ns for q in (o / "results").rglob("results.csv")}
    assert second[o / "results" / "unperturbed" / "results.csv"] == first[o / "results" / "unperturbed" /
                                                                          "results.csv"]
    assert second[o / "results" / "rotation-1" / "results.csv"] != first[o / "results" / "rotation-1" /
                                                                         "results.csv"]


@pytest.mark.parametrize(("body", "message"), [
    ('[levels]\nfoo = [1]\n', "[levels] foo: unknown perturbation kind 'foo'"),
    ('[levels]\nrotation = [1, 50]\n', "[levels] rotation[1] 'rotation=50': rotation level must be at most 45"),
    ('[levels]\njpeg = [80, 101]\n', "jpeg level must be in 1..100"),
    ('[levels]\njpeg = [80.5]\n', "jpeg level must be an integer"),
    ('[levels]\nvignetting_each = [0.5, 1]\n', "[levels] vignetting_each[1] 'vignetting_each=1': vignetting_each "
                                              "level must be at most 0.999"),
    ('[levels]\nresponse = [1, 2.5]\n', "[levels] response[1] 'response=2.5': response level must be at most 2"),
    ('[levels]\nnoise = [0, 2]\n', "[levels] noise[0]: level 0 (the unperturbed frames) is always run"),
    ('[levels]\nnoise = [2, 2]\n', "[levels] noise: lists a level twice"),
    ('[levels]\nnoise = ["2"]\n', "[levels] noise[0]: a level must be a number"),
    ('[levels]\nnoise = []\n', "[levels] noise: must be a non-empty list"),
    ('colour = 1\n[levels]\nnoise = [2]\n', "unknown key(s) colour"),
    ('seed = -1\n[levels]\nnoise = [2]\n', "seed must be a non-negative integer"),
    ('seed = 1.5\n[levels]\nnoise = [2]\n', "seed: expected an integer, got 1.5"),
    ('method = ["nope:x"]\n[levels]\nnoise = [2]\n', "method: unknown method"),
    ('frames = ["synthetic_box/vp009"]\n[levels]\nnoise = [2]\n', "frames: 'synthetic_box/vp009' is not a frame"),
    ('frames = ["vp000"]\n[levels]\nnoise = [2]\n', "frames: 'vp000' is not a <scene>/<viewpoint> label"),
    ('', "[levels]: missing"),
    ('[levels]\nnoise = [2]\ntranslation = [1, 200]\n', "[levels] translation = 200 (seed 0): translation=200.0: the "
                                                        "told rig of"),
])
def test_bad_files_are_one_line_exit_2_and_write_nothing(source, tmp_path, capsys, body, message):
    path = tmp_path / "bad.toml"
    path.write_text(f'kind = "robustness"\ndata = "{source}"\n' + body, encoding="utf-8")
    assert main(["study", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err and str(path) in err, err
    assert not (tmp_path / "o").exists()


def test_the_per_camera_photometric_kinds_are_accepted_as_levels(tmp_path):
    path = tmp_path / "r.toml"
    path.write_text('kind = "robustness"\ndata = "d"\n[levels]\nresponse = [0.5, 2]\nvignetting_each = [0.6, 0.2]\n'
                    'vignetting = [0.4]\n', encoding="utf-8")
    spec = rob.load_robustness(path)
    assert spec.levels == {"vignetting": (0.4,), "vignetting_each": (0.6, 0.2), "response": (0.5, 2.0)}
    assert [p.name for p in rob.plan_points(spec)] == ["unperturbed", "vignetting-0.4", "vignetting_each-0.6",
                                                       "vignetting_each-0.2", "response-0.5", "response-2"]
    assert [p.applies for p in rob.plan_points(spec)][-1] == [("response", 2.0)]


def test_missing_data_root_is_one_line_exit_2(tmp_path, capsys):
    path = tmp_path / "r.toml"
    path.write_text(STUDY.format(data=tmp_path / "nowhere", method=METHOD), encoding="utf-8")
    assert main(["study", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "nowhere" in err and "does not exist" in err
    assert not (tmp_path / "o").exists()
    path.write_text('kind = "robustness"\n[levels]\nnoise = [2]\n', encoding="utf-8")
    assert main(["study", str(path), "--out", str(tmp_path / "o")]) == 2
    assert "data: missing" in capsys.readouterr().err


@pytest.mark.slow
def test_another_metric_is_refused(study, capsys):
    path, out = study
    assert main(["study", str(path), "--out", str(out), "--metric", "rmse_m"]) == 2
    assert "--metric rmse_m: a robustness study" in capsys.readouterr().err


def test_a_wrong_kind_is_refused_by_the_grid_study(tmp_path, capsys):
    path = tmp_path / "r.toml"
    path.write_text('kind = "robust"\n[render]\nscene = "synthetic_box"\n', encoding="utf-8")
    assert main(["study", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "kind = 'robust'" in err and "robustness" in err


def test_doubling_level_interpolates_linearly_between_measured_levels():
    # base 0.1 at 0; 0.15 at 0.25; 0.3 at 0.5: reaches 0.2 a third of the way from 0.25 to 0.5
    assert doubling_level(0, 0.1, [0.25, 0.5, 1.0], [0.15, 0.3, 0.9]) == pytest.approx(0.25 + 0.25 / 3, abs=1e-12)
    # on the first segment, from the origin
    assert doubling_level(0, 0.1, [1.0], [0.5]) == pytest.approx(0.25, abs=1e-12)
    # exactly at a measured level
    assert doubling_level(0, 0.1, [1.0, 2.0], [0.15, 0.2]) == pytest.approx(2.0, abs=1e-12)
    # a level falling from the origin (JPEG quality): 100 -> 80 -> 40
    assert doubling_level(100, 0.1, [80, 40], [0.12, 0.32]) == pytest.approx(80 - 40 * 0.08 / 0.2, abs=1e-9)
    # never within the measured range, a NaN before the crossing, no usable base
    assert math.isnan(doubling_level(0, 0.1, [1.0, 2.0], [0.15, 0.19]))
    assert math.isnan(doubling_level(0, 0.1, [1.0, 2.0], [float("nan"), 0.5]))
    assert math.isnan(doubling_level(0, float("nan"), [1.0], [0.5]))
    assert math.isnan(doubling_level(0, 0.0, [1.0], [0.5]))


def test_kind_table_on_a_hand_made_table():
    rows = pd.DataFrame([
        # kind, level, method, frame, mae_m, valid_px: two frames pooled by their pixels
        ("none", 0, "a", "f1", 0.1, 100), ("none", 0, "a", "f2", 0.4, 300),
        ("rotation", 0.5, "a", "f1", 0.4, 100), ("rotation", 0.5, "a", "f2", 0.8, 300),
        ("rotation", 1.0, "a", "f1", 1.0, 100), ("rotation", 1.0, "a", "f2", 1.0, 300),
        ("none", 0, "b", "f1", 0.2, 100), ("rotation", 0.5, "b", "f1", 0.25, 100),
        ("rotation", 1.0, "b", "f1", 0.3, 100),
    ], columns=["kind", "level", "method", "frame", "mae_m", "valid_px"])
    table = kind_table(pooled_mae(rows), "rotation", [0.5, 1.0], 0, ["a", "b"])
    assert list(table.columns) == ["none", "0.5", "1", "doubles_at"]
    assert table.loc["a", "none"] == pytest.approx(0.325, abs=1e-12)  # (0.1*100 + 0.4*300) / 400
    assert table.loc["a", "0.5"] == pytest.approx(0.7, abs=1e-12)
    assert table.loc["a", "doubles_at"] == pytest.approx(0.5 * 0.325 / 0.375, abs=1e-12)
    assert math.isnan(table.loc["b", "doubles_at"])


@pytest.mark.slow
def test_the_shipped_study_takes_one_dev_frame_per_family_and_its_told_rigs_are_possible():
    spec = rob.load_robustness(ROOT / "studies" / "robustness.toml")
    suite = load_suite(ROOT / "suites" / "tri360-v1.toml")
    family = {f.label: f.entry.family for f in suite.frames("dev")}
    assert [family[f] for f in spec.frames] == ["classroom", "seminar", "lab", "corridor", "office", "library"]
    assert spec.methods == rob.ROBUSTNESS_METHODS
    assert spec.data == Path("data-dev")
    assert all(family_rig.baseline_m == 0.4 and family_rig.tilt_max_rad == 0.0 for family_rig in
               (f.entry.rig for f in suite.frames("dev") if f.label in spec.frames))
    # the comment's claim: at this seed every translation level gives a possible told rig for a level 0.4 m rig at
    # any heading
    frame = make_synthetic_frame(width=64)
    c = frame.cameras["C"].position
    for psi in np.linspace(0.0, 2.0 * np.pi, 72, endpoint=False):
        turn = rotation_about(np.array([0.0, 0.0, 1.0]), psi)
        cams = {n: CameraPose(c + turn @ (p.position - c), turn @ p.rotation) for n, p in frame.cameras.items()}
        turned = dataclasses.replace(frame, cameras=cams)
        for level in spec.levels["translation"]:
            new = perturb_frame(turned, [("translation", level)], spec.seed, {"path": "x", "sha256": "y"})
            validate_metadata(new.metadata(), Path("frame.json"))
