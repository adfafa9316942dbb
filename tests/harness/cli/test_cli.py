"""The tri360 command line: reconstruct and evaluate on synthetic frames, and one-line errors."""

import json
import os
import subprocess
import sys

import pandas as pd
import pytest

from harness.cli import build_parser, main
from harness.data.exr import read_float_map
from reconstruction.methods.registry import DEFAULT_METHOD, PRESETS, get_methods
from reports.schema import RESULT_COLUMNS


@pytest.mark.slow
@pytest.mark.parametrize("variant", ["average", "angle", "gradient", "color"])
def test_reconstruct_writes_predictions(synthetic_root, tmp_path, capsys, variant):
    out = tmp_path / "rec"
    assert main(["reconstruct", str(synthetic_root / "synthetic_box" / "vp000"), "--flow", "oracle", "--variant",
                 variant, "--out", str(out), "--quiet"]) == 0
    text = capsys.readouterr().out
    d = read_float_map(out / "synthetic_box" / "vp000" / "distance.exr", "distance")
    assert d.shape == (100, 200) and f"oracle-rect:{variant}" in text and "MAE" in text
    info = json.loads((out / "synthetic_box" / "vp000" / "reconstruction.json").read_text())
    assert json.loads((out / "method.json").read_text())["name"] == f"oracle-rect:{variant}"
    # oracle: exact geometry (metres); the colour term moves distances by the views' sub-pixel intensity
    # differences, which at this 200 x 100 size (a pixel spans ~3 cm at 1 m) is a few millimetres
    assert info["metrics"]["mae_m"] < (5e-3 if variant == "color" else 1e-3)


@pytest.mark.slow
def test_reconstruct_default_method_and_one_method_only(synthetic_root, tmp_path, capsys):
    frame = str(synthetic_root / "synthetic_box" / "vp000")
    assert main(["reconstruct", frame, "--out", str(tmp_path / "a"), "--quiet"]) == 0
    assert DEFAULT_METHOD in capsys.readouterr().out
    assert main(["reconstruct", frame, "--out", str(tmp_path / "b"), "--method", "dis-rect:angle", "--flow",
                 "dis"]) == 2
    assert "do not combine" in capsys.readouterr().err and not (tmp_path / "b").exists()


@pytest.mark.slow
def test_evaluate_writes_results_schema(synthetic_root, tmp_path, capsys):
    out = tmp_path / "res"
    assert main(["evaluate", str(synthetic_root), "--out", str(out), "--flow", "oracle", "dis",
                 "--variants", "average", "gradient", "--no-report"]) == 0
    table = pd.read_csv(out / "results.csv")
    assert list(table.columns) == RESULT_COLUMNS
    assert len(table) == 2 * 2 * 2  # frames x flows x variants
    assert set(table.method) == {"oracle-rect:average", "oracle-rect:gradient", "dis-rect:average",
                                 "dis-rect:gradient"}
    assert (table[table.flow == "oracle"].mae_m < 1e-3).all()
    assert json.loads((out / "results.json").read_text())[0].keys() == set(RESULT_COLUMNS)
    assert (out / "breakdown.csv").exists() and (out / "frames.json").exists()
    assert (out / "maps/synthetic_box/vp001/dis-rect/gradient.distance.exr").exists()
    assert "MAE" in capsys.readouterr().out


@pytest.mark.parametrize("argv, culprit", [
    (["evaluate", "/nonexistent/root"], "/nonexistent/root"),
    (["reconstruct", "/nonexistent/frame", "--out", "x"], "frame.json"),
    (["evaluate", "{root}", "--variants", "average", "bogus"], "bogus"),
])
def test_errors_are_one_line_and_non_zero(argv, culprit, synthetic_root, capsys):
    argv = [a.replace("{root}", str(synthetic_root)) for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and culprit in err[0] and "error" in err[0]


def test_a_repeated_list_option_adds_to_the_list():
    """``--method a --method b`` asks for both (as ``--method a b``), not only the last."""
    args = build_parser().parse_args(["evaluate", "data", "--method", "fused-mirror", "--method", "sweep",
                                      "--scene", "a", "--scene", "b", "c"])
    assert args.method == ["fused-mirror", "sweep"] and args.scene == ["a", "b", "c"]
    args = build_parser().parse_args(["evaluate", "data", "--flow", "dis", "--flow", "deepflow", "--variants",
                                      "average", "--variants", "gradient"])
    assert args.flow == ["dis", "deepflow"] and args.variants == ["average", "gradient"] and args.method is None
    args = build_parser().parse_args(["score", "p1", "p2", "--data", "d", "--method", "a", "--method", "b"])
    assert args.method == ["a", "b"]


def test_empty_root_is_an_error(tmp_path, capsys):
    assert main(["evaluate", str(tmp_path)]) == 2
    assert "no tri360 frames" in capsys.readouterr().err


def test_unknown_flow_is_one_line(synthetic_root, tmp_path, capsys):
    assert main(["evaluate", str(synthetic_root), "--out", str(tmp_path / "r"), "--flow", "nope"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown flow 'nope'" in err[0] and "dis" in err[0]
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize("argv, line", [
    (["evaluate", "{root}", "--method", "deepflowdm-rect:gradient"],
     "tri360 evaluate: error: deepflowdm-rect:gradient is now called deepflow-rect:gradient"),
    (["evaluate", "{root}", "--flow", "deepflowdm"], "tri360 evaluate: error: flow deepflowdm is now called deepflow"),
    (["reconstruct", "{root}/synthetic_box/vp000", "--out", "{out}", "--flow", "deepflowdm"],
     "tri360 reconstruct: error: flow deepflowdm is now called deepflow"),
])
def test_renamed_labels_name_their_new_one(argv, line, synthetic_root, tmp_path, capsys):
    argv = [a.replace("{root}", str(synthetic_root)).replace("{out}", str(tmp_path / "p")) for a in argv]
    assert main(argv) == 2
    assert capsys.readouterr().err.strip().splitlines() == [line]
    assert not (tmp_path / "p").exists()


def test_methods_lists_presets_flows_variants_and_defaults(capsys):
    assert main(["methods"]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    named = lines[1:1 + len(PRESETS)]
    assert [ln.split()[0] for ln in named] == [p.label + ("*" if p.label == DEFAULT_METHOD else "") for p in PRESETS]
    for p, ln in zip(PRESETS, named, strict=True):
        assert ln.endswith(p.description)
    flows = {ln.split()[0]: ln for ln in lines if ln.startswith("    ")}
    assert {"deepflow", "deepflow-opencv", "dis", "oracle", "average", "gradient"} <= set(flows)
    assert "as published" in flows["deepflow"] and "paper's set-up: deepflow-rect" in flows["deepflow"]
    assert "OpenCV" in flows["deepflow-opencv"] and "tri360's flow" in flows["dis"]
    assert ("'tri360 evaluate' runs by default: fused-mirror, sweep, dis-rect:{average,angle,gradient,color}, "
            "deepflow-rect:{average,angle,gradient,color}") in lines


def test_methods_show_prints_what_config_json_records(synthetic_root, tmp_path, capsys):
    """``tri360 methods --show LABEL``: the method's whole configuration, the entry ``config.json`` of a results set
    records for it; the default's in full, the paper's set-up with DeepFlow's and DeepMatching's parameters."""
    out = tmp_path / "res"
    assert main(["evaluate", str(synthetic_root), "--out", str(out), "--method", "oracle-rect:average",
                 "--no-report", "--quiet"]) == 0
    recorded = json.loads((out / "config.json").read_text())["methods"]["oracle-rect:average"]
    capsys.readouterr()
    assert main(["methods", "--show", "oracle-rect:average"]) == 0
    assert json.loads(capsys.readouterr().out) == recorded
    assert main(["methods", "--show", "fused-mirror"]) == 0
    shown = json.loads(capsys.readouterr().out)
    assert shown == json.loads(json.dumps(get_methods(["fused-mirror"])[0].config()))
    assert shown["sweep"]["corrected_cost"]["intensity_weight"] == 0.25
    assert shown["flow"]["photometric"]["prepass_flow"]["params"]["var_iterations"] == 10
    assert shown["flow"]["rig"]["max_matches"] == 40000
    assert main(["methods", "--show", "deepflow-rect:gradient"]) == 0
    params = json.loads(capsys.readouterr().out)["flow"]["params"]
    assert {"alpha": 6.0, "beta": 390.0, "n_solver": 25, "downscale": 1, "hog_sigmoid": 0.2}.items() <= params.items()


def test_methods_show_of_an_unknown_label_is_one_line(capsys):
    assert main(["methods", "--show", "nope"]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert captured.out == "" and len(err) == 1
    assert err[0].startswith("tri360 methods: error: unknown method(s) nope (named methods: fused-mirror")


@pytest.mark.slow
def test_report_names_the_results_set_where_it_lives(synthetic_root, tmp_path, capsys):
    """evaluate builds the set in a hidden staging directory and swaps it in: the page names --out, not the stage."""
    out = tmp_path / "res"
    assert main(["evaluate", str(synthetic_root), "--out", str(out), "--flow", "oracle", "--variants", "average",
                 "--quiet"]) == 0
    page = (out / "report.html").read_text()
    header = next(ln for ln in page.splitlines() if "results: " in ln)
    assert f"results: {out.resolve()} &middot;" in header and "partial" not in header


@pytest.mark.slow
@pytest.mark.parametrize("args", [["methods"], ["scenes", "--params"]])
def test_a_listing_into_a_closed_pipe_stops_quietly(args):
    """``tri360 methods | head``: when stdout's reader has gone, the command prints nothing on stderr (no
    "Broken pipe" error line, no traceback at exit) and exits 141 (128 + SIGPIPE), as a pipeline expects."""
    read_end, write_end = os.pipe()
    os.close(read_end)  # no reader at all: the first write fails
    try:
        proc = subprocess.run([sys.executable, "-m", "harness.cli", *args], stdout=write_end,
                              stderr=subprocess.PIPE, timeout=300)
    finally:
        os.close(write_end)
    assert proc.stderr.decode() == "" and proc.returncode == 141
