"""The validation job of the ground-truth-free quality measures (``python -m tools.research.validate_quality``) on
tiny ray-cast frames: its outputs, the calibration check, reuse of a results set's maps and the refusals."""

from __future__ import annotations

import contextlib
import dataclasses
import io
import json
import math

import numpy as np
import pandas as pd
import pytest

from harness.commands.evaluate import evaluate
from harness.data import jsonio
from harness.data.frame import write_frame
from harness.data.outputs import read_marker
from harness.render.raycast import render_frame
from harness.runtime.context import QUIET
from reconstruction.methods import presets
from reconstruction.methods.registry import get_methods
from reconstruction.methods.sweep import SweepMethod
from reconstruction.quality import CALIBRATION_THRESHOLD, FACTORS, UNCERTAINTY_FACTORS
from reconstruction.sweep.planes import PlaneParams
from reports.quality_validation import MEASURES, choose_subset, choose_threshold, factor_subsets, rank_correlation
from scenes.model import choose_viewpoints
from scenes.registry import get_scene
from tests.helpers import make_synthetic_frame
from tools.research.validate_quality import calibration_choice, config_difference, frame_family, main

WIDTH = 200
METHOD = "sweep"
RHO_COLUMNS = [f"rho:{m}" for m in (*MEASURES, "confidence") if m != "disagreement"]  # sweep: no reference


def _box_room_frame():
    entry, preset = get_scene("box_room")
    spec = entry.spec(preset, seed=4)
    return render_frame(spec, choose_viewpoints(spec, 1, 4)[0], WIDTH, "box_room", "vp000")


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    """A data root of three 200x100 ray-cast frames of two families (synthetic_box vp000/vp001, box_room)."""
    root = tmp_path_factory.mktemp("qval") / "data"
    for vp in (0, 1):
        write_frame(make_synthetic_frame(width=WIDTH, viewpoint=vp), root)
    write_frame(_box_room_frame(), root)
    return root


def _run(capsys, *args) -> tuple[int, str, str]:
    capsys.readouterr()
    code = main([str(a) for a in args])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


@pytest.fixture(scope="module")
def validated(data):
    """The job run on ``data`` with ``sweep`` (2 calibration frames): ``(out, exit status, stdout)``."""
    out = data.parent / "val"
    buf_out, buf_err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(buf_out), contextlib.redirect_stderr(buf_err):
        code = main([str(data), "--method", METHOD, "--out", str(out), "--calibration-frames", "2", "--quiet"])
    assert buf_err.getvalue() == ""
    return out, code, buf_out.getvalue()


@pytest.mark.slow
def test_outputs_exist_and_parse(data, validated):
    out, code, text = validated
    assert code == 0
    rows = pd.read_csv(out / "validation.csv")
    assert sorted(zip(rows["scene"], rows["viewpoint"], strict=True)) == [
        ("box_room", "vp000"), ("synthetic_box", "vp000"), ("synthetic_box", "vp001")]
    assert set(rows["family"]) == {"box_room", "synthetic_box"}
    for col in RHO_COLUMNS:  # sweep gives a confidence: every column has a value
        rho = rows[col].to_numpy(float)
        assert np.isfinite(rho).all() and (np.abs(rho) <= 1.0).all(), col
    assert (rows["valid_px"] > 0.9 * WIDTH * WIDTH / 2).all()
    assert np.isfinite(rows["ause_m:uncertainty"]).all()
    summary = json.loads((out / "validation.json").read_text())
    assert summary["frames"] == 3 and summary["data_root"] == str(data.resolve())
    assert summary["method"]["configuration"] == jsonio.to_jsonable(SweepMethod().config())
    assert set(summary["software"]) == {"tri360_version", "commit"}
    assert summary["ranking"]["all"]["mean"] == pytest.approx(rows["rho:uncertainty"].mean(), abs=1e-12)
    assert set(summary["ranking"]["families"]) == {"box_room", "synthetic_box"}
    assert -1.0 <= summary["ranking"]["all"]["pooled"]["rho:uncertainty"] <= 1.0
    md = (out / "validation.md").read_text()
    assert text == md and "| box_room | box_room/vp000 |" in md and "## Calibration check" in md
    assert read_marker(out)["kind"] == "validation"


@pytest.mark.slow
def test_calibration_check_flags_the_rotated_frames(validated):
    out, code, _ = validated
    assert code == 0
    calib = pd.read_csv(out / "calibration.csv")
    # round-robin over the families: one frame of each
    assert sorted(calib["family"]) == ["box_room", "synthetic_box"] and (calib["rotation_deg"] == 0.5).all()
    # on these exact ray-cast frames the exact score (degrees) is about 0.015-0.034 and the rotated one 0.50-0.54
    # (measured): the assertions keep wide margins around the threshold
    assert (calib["exact_score"] < min(CALIBRATION_THRESHOLD, 0.1)).all()
    assert (calib["perturbed_score"] > max(CALIBRATION_THRESHOLD, 0.3)).all()
    assert calib["separated"].all()
    summary = json.loads((out / "validation.json").read_text())["calibration"]
    assert summary["separated"] == 2 and summary["frames"] == 2 and summary["every_perturbed_above_every_exact"]


@pytest.fixture(scope="module")
def results(data):
    """A results set of ``evaluate`` holding ``sweep`` under another label and a sweep of another configuration."""
    out = data.parent / "res"
    other = dataclasses.replace(SweepMethod(), pairs=("U",), label="sweep-u")
    evaluate(data, out, [SweepMethod(label="sweep-b"), other], report=False, ctx=QUIET)
    return out


@pytest.mark.slow
def test_results_reuse_gives_the_same_rho_as_running_the_method(data, validated, results, tmp_path, capsys):
    out = tmp_path / "val-reused"
    code, text, err = _run(capsys, data, "--method", METHOD, "--out", out, "--results", results,
                           "--results-label", "sweep-b", "--calibration-frames", "0", "--quiet")
    assert code == 0, err
    ran = pd.read_csv(validated[0] / "validation.csv").set_index(["scene", "viewpoint"])
    reused = pd.read_csv(out / "validation.csv").set_index(["scene", "viewpoint"]).loc[ran.index]
    for col in [*RHO_COLUMNS, "mae_m", "ause_m:uncertainty"]:
        np.testing.assert_allclose(reused[col], ran[col], rtol=0, atol=1e-9, err_msg=col)
    summary = json.loads((out / "validation.json").read_text())
    assert summary["distances"] == {"source": "results set", "path": str(results.resolve()), "label": "sweep-b"}
    assert summary["calibration"]["frames"] == 0 and "Not run" in text


@pytest.mark.slow
def test_results_of_another_configuration_or_label_are_refused_in_one_line(data, results, tmp_path, capsys):
    out = tmp_path / "val"
    for label, words in (("sweep-u", ["'sweep-u'", "another configuration", "pairs"]),
                         ("absent", ["'absent'", "records no method"])):
        code, _, err = _run(capsys, data, "--method", METHOD, "--out", out, "--results", results,
                            "--results-label", label, "--quiet")
        assert code == 2 and len(err.strip().splitlines()) == 1, err
        assert all(w in err for w in words), err
        assert not out.exists()


@pytest.mark.slow
def test_bad_inputs_are_one_line_and_exit_2(data, tmp_path, capsys):
    a_file = tmp_path / "file.txt"
    a_file.write_text("x", encoding="utf-8")
    cases = [
        ([tmp_path / "missing", "--method", METHOD, "--out", tmp_path / "o1"], "missing"),
        ([data, "--method", "no-such-method", "--out", tmp_path / "o2"], "no-such-method"),
        ([data, "--method", METHOD, "--out", a_file], str(a_file)),
        ([data, "--method", METHOD, "--out", data / "inside"], "input"),
        ([data, "--method", METHOD, "--out", tmp_path / "o3", "--rotation", "-1"], "--rotation"),
        ([data, "--method", METHOD, "--out", tmp_path / "o4", "--results-label", "x"], "--results"),
        ([data, "--method", METHOD, "--out", tmp_path / "o5", "--results", tmp_path / "no-results"], "no-results"),
    ]
    for args, word in cases:
        code, out, err = _run(capsys, *args, "--quiet")
        assert code == 2 and len(err.strip().splitlines()) == 1 and word in err, (args, err)
        assert out == ""
    assert not any((tmp_path / f"o{i}").exists() for i in range(1, 6))
    assert a_file.read_text(encoding="utf-8") == "x" and not (data / "inside").exists()


@pytest.mark.slow
def test_a_data_root_without_ground_truth_is_refused(data, tmp_path, capsys):
    root = tmp_path / "nogt"
    write_frame(dataclasses.replace(make_synthetic_frame(width=64), distance={}), root)
    code, _, err = _run(capsys, root, "--method", METHOD, "--out", tmp_path / "o", "--quiet")
    assert code == 2 and len(err.strip().splitlines()) == 1 and "ground-truth" in err, err


def test_calibration_frames_go_round_robin_over_sorted_families():
    keys = [("a-s1", "vp000"), ("a-s1", "vp001"), ("a-s1", "vp002"), ("b-s2", "vp000"), ("c-s3", "vp000")]
    fams = {k: k[0].split("-")[0] for k in keys}
    assert calibration_choice(keys[::-1], fams, 4) == [("a-s1", "vp000"), ("b-s2", "vp000"), ("c-s3", "vp000"),
                                                      ("a-s1", "vp001")]
    assert len(calibration_choice(keys, fams, 10)) == 5 and calibration_choice(keys, fams, 0) == []


def test_family_from_provenance_else_from_the_suite_scene_name():
    assert frame_family("classroom-lecture-s1003", "classroom") == "classroom"
    assert frame_family("classroom-lecture-s1003", "") == "classroom-lecture"
    assert frame_family("seminar-s1011", "") == "seminar" and frame_family("hall", "") == "hall"


def test_configurations_compare_without_their_label():
    base = SweepMethod().config()
    assert config_difference({**base, "label": "renamed"}, base) is None
    other = dataclasses.replace(SweepMethod(), pairs=("U",)).config()
    assert config_difference(other, base) == "pairs: ['U'] vs ['U', 'R']"
    assert config_difference({**base, "kind": "fused"}, base).startswith("kind:")
    fused = presets.fused()
    renamed = dataclasses.replace(fused, label="fused-b", sweep=dataclasses.replace(fused.sweep, label="sweep-b"))
    assert config_difference(renamed.config(), fused.config()) is None  # labels inside a method are names too
    walls = dataclasses.replace(fused, sweep=dataclasses.replace(fused.sweep, planes=PlaneParams(wall_labels=9)))
    assert config_difference(walls.config(), fused.config()).startswith("sweep.planes.wall_labels: 9 vs ")
    # what the quality is compared with does not change the distance: a stored map stays usable
    checked = dataclasses.replace(fused, quality_flow=fused.flow)
    assert "quality_flow" in checked.config() and "quality_flow" not in fused.config()
    assert config_difference(fused.config(), checked.config()) is None


def test_a_configuration_written_before_a_parameter_was_added_reads_as_its_earlier_value():
    """Results sets from before ``planes.mirror_tolerance`` existed ran without the mirror test: usable for a method
    with the test off, not for one with it on."""
    from reconstruction.methods.registry import uncalibrated

    old = json.loads(json.dumps(uncalibrated(presets.fused_gated()).config()))  # as fused-gated ran before both
    del old["sweep"]["planes"]["mirror_tolerance"], old["sweep"]["cost"]["intensity_weight"]
    del old["sweep"]["planes"]["bound_penalty"]  # before it existed: labels beyond the room bound forbidden
    del old["sweep"]["planes"]["bound_penalty_min_az"]  # before it existed: the penalty at every bearing
    for part in ("flow", "sweep", "quality_flow"):
        del old[part]["photometric"]
    assert config_difference(old, uncalibrated(presets.fused_gated()).config()) is None
    assert config_difference(old, presets.fused_gated().config()) == "flow.photometric.mode: 'none' vs 'gain-field'"
    raw_mirror = uncalibrated(presets.fused_mirror()).config()
    # the mirror test is where they differ once the raw default's sweep labels, room bound, refill and untextured
    # pixels' cost are fused-gated's
    raw_mirror["sweep"]["cost"]["levels"] = old["sweep"]["cost"]["levels"]
    raw_mirror["sweep"]["planes"]["bound_margin"] = old["sweep"]["planes"]["bound_margin"]
    raw_mirror["sweep"]["planes"]["bound_penalty"] = 0.0
    raw_mirror["sweep"]["planes"]["bound_penalty_min_az"] = 0.0
    raw_mirror["sweep"]["post"] = old["sweep"]["post"]
    for k in ("flat_contrast", "flat_weight"):
        raw_mirror["sweep"]["cost"][k] = old["sweep"]["cost"][k]
    for k in ("epipole_cone_deg", "epipole_cone_noise_low", "epipole_cone_noise_high", "epipole_cone_room"):
        raw_mirror["prior"][k] = 0.0
    assert config_difference(old, raw_mirror) == "sweep.planes.mirror_tolerance: 0.0 vs 0.2"
    assert config_difference(presets.fused_gated().config(), old) == "flow.photometric: present vs absent"


def test_a_configuration_from_before_the_constants_became_parameters_reads_as_their_values():
    """Results sets written before the pre-pass flow, the fits' limits, the evidence's blocks, the rig fit's
    iterations, the noise blur's cap, the fill's space, the edge snapping, the floor and ceiling families, the
    hemisphere checks and DeepFlow's and DeepMatching's parameters were recorded ran with the values they have by
    default: usable for the default and the paper's set-up, not for other values."""
    now = presets.fused_mirror().config()
    old = json.loads(json.dumps(now))
    for key in ("prepass_flow", "max_fit_pixels", "longitude_blocks", "min_block_samples", "hemispheres"):
        del old["flow"]["photometric"][key], old["sweep"]["photometric"][key]
    for key in ("iterations", "tukey_c", "max_matches", "longitude_blocks", "min_block_samples", "hemispheres"):
        del old["flow"]["rig"][key]
    del old["sweep"]["cost"]["max_noise_blur_px"], old["sweep"]["corrected_cost"]["max_noise_blur_px"]
    for key in ("fill_space", "edge_radius_px", "edge_sigma_color", "edge_sigma_px", "edge_jump", "edge_reach_px"):
        del old["sweep"]["post"][key]
    del old["sweep"]["planes"]["room_labels"], old["sweep"]["planes"]["room_spread"]
    assert config_difference(old, now) is None
    tighter = dataclasses.replace(presets.fused_mirror().flow.rig, iterations=3)
    changed = dataclasses.replace(presets.fused_mirror(), flow=dataclasses.replace(presets.fused_mirror().flow,
                                                                                   rig=tighter))
    assert config_difference(old, changed.config()) == "flow.rig.iterations: 6 vs 3"
    halves = dataclasses.replace(presets.fused_mirror().flow.rig, hemispheres=1.0)
    changed = dataclasses.replace(presets.fused_mirror(), flow=dataclasses.replace(presets.fused_mirror().flow,
                                                                                   rig=halves))
    assert config_difference(old, changed.config()) == "flow.rig.hemispheres: 0.0 vs 1.0"
    del old["flow"]["rig"]["confirm_factor"]  # stored before the confirming pass: it ran without one
    assert config_difference(old, now) == "flow.rig.confirm_factor: 0 vs 1"
    paper = get_methods(["deepflow-rect:gradient"])[0]
    old = json.loads(json.dumps(paper.config()))
    old["flow"]["params"] = {k: old["flow"]["params"][k] for k in ("downscale", "ngh_rad_x", "ngh_rad_y", "wrap")}
    assert config_difference(old, paper.config()) is None
    smoother = dataclasses.replace(paper.flow, params={**paper.flow.params, "alpha": 3.0})
    assert config_difference(old, dataclasses.replace(paper, flow=smoother).config()) == "flow.params.alpha: 6.0 vs 3.0"


def test_rank_correlation_counts_nan_as_most_uncertain():
    err = np.array([0.1, 0.2, 0.3, 0.4])
    assert rank_correlation(np.array([1.0, 2.0, 3.0, np.nan]), err) == pytest.approx(1.0, abs=1e-12)
    assert rank_correlation(np.array([4.0, 3.0, 2.0, 1.0]), err) == pytest.approx(-1.0, abs=1e-12)
    assert math.isnan(rank_correlation(np.ones(4), err)) and math.isnan(rank_correlation(np.ones(2), err[:2]))


@pytest.mark.slow
def test_frames_without_ground_truth_are_skipped_and_frames_keeps_the_first(tmp_path, capsys):
    root = tmp_path / "mixed"
    for vp in (1, 0):
        write_frame(make_synthetic_frame(width=96, viewpoint=vp), root)
    write_frame(dataclasses.replace(make_synthetic_frame(width=96), scene="real", distance={}), root)
    out = tmp_path / "val"
    code, _, err = _run(capsys, root, "--method", METHOD, "--out", out, "--frames", "1", "--calibration-frames", "0",
                        "--quiet")
    assert code == 0, err
    rows = pd.read_csv(out / "validation.csv")
    assert list(zip(rows["scene"], rows["viewpoint"], strict=True)) == [("synthetic_box", "vp000")]
    summary = json.loads((out / "validation.json").read_text())
    assert summary["frames"] == 1 and summary["skipped_without_ground_truth"] == [str(root / "real" / "vp000")]


def test_factor_subsets_cover_every_product_and_the_best_mean_wins():
    subsets = factor_subsets()
    assert len(subsets) == 2 ** len(FACTORS) - 1 and len(set(subsets)) == len(subsets)
    assert subsets[0] == (FACTORS[0],) and subsets[-1] == tuple(FACTORS)
    assert tuple(UNCERTAINTY_FACTORS) in subsets
    assert choose_subset({"factors:a": 0.4, "factors:a*b": 0.5, "factors:b": float("nan")}) == "factors:a*b"
    assert choose_subset({"factors:a": 0.5, "factors:a*b": 0.5}) == "factors:a"  # a tie: the smaller one
    assert choose_subset({"factors:a": float("nan")}) is None


def test_threshold_separates_most_frames_in_the_middle_of_the_widest_gap():
    # exact scores all below every perturbed one: the middle of the gap between the highest exact and lowest
    # perturbed score
    t = choose_threshold([-0.10, -0.05, -0.03], [0.2, -0.01, 0.05])
    assert t == {"threshold": pytest.approx(-0.02), "separated": 3, "frames": 3}
    # overlap: one frame cannot be separated; the threshold keeps the other two
    t = choose_threshold([-0.10, 0.10], [0.30, 0.05])
    assert t["separated"] == 1 and -0.10 < t["threshold"] < 0.30
    assert np.isnan(choose_threshold([float("nan")], [float("nan")])["threshold"])


@pytest.mark.slow
def test_a_fused_method_ranks_with_its_flow_as_reference(data, tmp_path, capsys):
    """fused hands back its flow distance: the disagreement column is filled and, from a results set, the
    reference is read under the flow method's label (and refused, named, when the set lacks it)."""
    out = tmp_path / "val-fused"
    code, _, err = _run(capsys, data, "--method", "fused", "--out", out, "--frames", "1", "--calibration-frames", "0",
                        "--quiet")
    assert code == 0, err
    ran = pd.read_csv(out / "validation.csv")
    assert np.isfinite(ran["rho:disagreement"]).all()
    assert np.isfinite(ran["rho:factors:" + "*".join(UNCERTAINTY_FACTORS)]).all()
    fused = presets.fused()
    res = tmp_path / "res-fused"
    evaluate(data, res, [fused, fused.flow], report=False, ctx=QUIET, scenes=["box_room"])
    reused = tmp_path / "val-fused-reused"
    code, _, err = _run(capsys, data, "--method", "fused", "--out", reused, "--results", res, "--frames", "1",
                        "--calibration-frames", "0", "--quiet")
    assert code == 0, err
    again = pd.read_csv(reused / "validation.csv")
    for col in ("rho:uncertainty", "rho:disagreement"):
        np.testing.assert_allclose(again[col], ran[col], rtol=0, atol=1e-6, err_msg=col)
    alone = tmp_path / "res-alone"
    evaluate(data, alone, [fused], report=False, ctx=QUIET, scenes=["box_room"])
    code, _, err = _run(capsys, data, "--method", "fused", "--out", tmp_path / "v3", "--results", alone,
                        "--frames", "1", "--calibration-frames", "0", "--quiet")
    assert code == 2 and err.count("\n") == 1 and repr(fused.flow.label) in err and "reference" in err


def test_a_plane_search_stored_before_the_walls_step_reads_as_leaving_walls_alone():
    from tools.research.select_walls import walls_method

    old = json.loads(json.dumps(walls_method(0.0, 0.03).config()))
    for k in ("wall_margin", "wall_max_share"):
        del old["sweep"]["refine_planes"][k]
    assert config_difference(old, walls_method(0.0, 0.03).config()) is None
    wanted = {**json.loads(json.dumps(presets.fused_mirror().config())), "label": old["label"]}
    assert "wall_margin" in config_difference(old, wanted)


def test_a_sweep_stored_before_the_wall_yaw_option_reads_as_the_normals_vote():
    old = json.loads(json.dumps(presets.fused_gated().config()))
    del old["sweep"]["planes"]["wall_yaw"]
    assert config_difference(old, presets.fused_gated().config()) is None
    old = json.loads(json.dumps(presets.fused_mirror().config()))
    del old["sweep"]["planes"]["wall_yaw"]
    wanted = "sweep.planes.wall_yaw: 'normals' vs 'normals-or-offsets'"
    assert config_difference(old, presets.fused_mirror().config()) == wanted


@pytest.mark.parametrize("keys, wanted", [
    (("ceiling_edge",), "sweep.refine_planes.ceiling_edge: 0.0 vs 0.99"),
    (("closed_max_share", "closed_ceiling_share"), "sweep.refine_planes.closed_ceiling_share: 0.0 vs 0.04"),
], ids=["ceiling_edge", "closed_walls"])
def test_a_wall_step_stored_before_an_option_reads_as_without_it(keys, wanted):
    default = presets.fused_mirror()
    without = dataclasses.replace(default, sweep=dataclasses.replace(
        default.sweep, refine_planes=dataclasses.replace(default.sweep.refine_planes, **dict.fromkeys(keys, 0.0))))
    old = json.loads(json.dumps(without.config()))
    for key in keys:
        del old["sweep"]["refine_planes"][key]
    assert config_difference(old, without.config()) is None
    # the default stored without them reads as without them: the first that differs is named
    old = json.loads(json.dumps(default.config()))
    for key in keys:
        del old["sweep"]["refine_planes"][key]
    assert config_difference(old, default.config()) == wanted
