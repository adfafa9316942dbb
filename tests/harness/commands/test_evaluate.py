"""The evaluate job: methods + scoring, results keyed by frame, config.json, atomic result sets."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pandas as pd
import pytest

from harness.cli import main
from harness.commands.evaluate import evaluate, select_frames, summary_text
from harness.data.errors import UserError
from harness.data.frame import read_frame
from harness.data.results import read_regions, read_results
from harness.runtime.context import QUIET, RunContext
from reconstruction.methods.base import MethodOutput
from reconstruction.methods.registry import flow_methods
from reports.floor import floor_mae, frame_floor_sigma, region_floors
from reports.regions import regions
from reports.schema import RESULT_COLUMNS


class Constant:
    """An outside method predicting a constant distance, metres."""

    def __init__(self, value: float, label: str = "const"):
        self.label, self.value = label, value

    def config(self) -> dict:
        return {"kind": "constant", "value": self.value}

    def run(self, frame) -> MethodOutput:
        return MethodOutput(np.full((frame.height, frame.width), self.value, np.float32), seconds={"total": 0.5})


class Interrupting(Constant):
    def run(self, frame):
        raise KeyboardInterrupt


@pytest.mark.slow
def test_config_json_records_every_method_and_frame(synthetic_root, tmp_path):
    out = tmp_path / "res"
    methods = [*flow_methods(["oracle"], [True], ["average", "gradient"]), Constant(2.0)]
    table = evaluate(synthetic_root, out, methods, report=False, ctx=QUIET)
    assert list(table.columns) == RESULT_COLUMNS and len(table) == 2 * 3
    const = table[table.method == "const"]
    assert (const.flow.fillna("") == "").all() and (const.seconds == 0.5).all()
    cfg = json.loads((out / "config.json").read_text())
    assert set(cfg["methods"]) == {"oracle-rect:average", "oracle-rect:gradient", "const"}
    assert cfg["methods"]["oracle-rect:gradient"]["refine"]["gradient"] is True
    assert cfg["methods"]["oracle-rect:gradient"]["triangulation"]["d_min_m"] > 0
    assert cfg["software"]["tri360_version"] and "commit" in cfg["software"]
    assert [f["viewpoint"] for f in cfg["frames"]] == ["vp000", "vp001"]
    assert cfg["frames"][0]["renderer"]["engine"]
    assert (out / "maps/synthetic_box/vp000/const/distance.exr").is_file()
    assert (out / "maps/synthetic_box/vp000/oracle-rect/gradient.distance.exr").is_file()


def test_evaluate_a_single_frame_directory_and_scene_filter(synthetic_root, tmp_path):
    frame_dir = synthetic_root / "synthetic_box" / "vp001"
    refs = select_frames(frame_dir)
    assert [r.viewpoint for r in refs] == ["vp001"]
    assert main(["evaluate", str(frame_dir), "--scene", "synthetic_box", "--flow", "oracle", "--variants",
                 "average", "--out", str(tmp_path / "one"), "--no-report", "--quiet"]) == 0
    assert len(pd.read_csv(tmp_path / "one" / "results.csv")) == 1
    with pytest.raises(UserError, match="no frames of scene.*classroom.*scenes found: synthetic_box"):
        select_frames(synthetic_root, ["classroom"])


def test_two_frames_with_the_same_identity_are_refused(synthetic_root, tmp_path):
    root = tmp_path / "data"
    shutil.copytree(synthetic_root / "synthetic_box" / "vp000", root / "a" / "vp000")
    shutil.copytree(synthetic_root / "synthetic_box" / "vp000", root / "b" / "vp000")
    with pytest.raises(UserError, match="would overwrite each other"):
        select_frames(root)


@pytest.mark.slow
def test_interrupted_evaluate_keeps_the_previous_results_set(synthetic_root, tmp_path):
    out = tmp_path / "res"
    evaluate(synthetic_root, out, [Constant(2.0)], report=False, ctx=QUIET)
    before = (out / "results.csv").read_bytes()
    with pytest.raises(KeyboardInterrupt):
        evaluate(synthetic_root, out, [Constant(3.0), Interrupting(1.0, "stop")], report=False, ctx=QUIET)
    assert (out / "results.csv").read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["res"]  # no staging or old copies left


@pytest.mark.slow
def test_rerun_replaces_the_whole_results_set(synthetic_root, tmp_path):
    out = tmp_path / "res"
    evaluate(synthetic_root, out, [Constant(2.0, "a")], report=False, ctx=QUIET)
    (out / "notes.txt").write_text("a user's file: never replaced")
    with pytest.raises(UserError, match="notes.txt"):
        evaluate(synthetic_root, out, [Constant(3.0, "b")], report=False, ctx=QUIET)
    assert (out / "notes.txt").exists()
    (out / "notes.txt").unlink()
    evaluate(synthetic_root, out, [Constant(3.0, "b")], report=False, ctx=QUIET)
    assert set(pd.read_csv(out / "results.csv").method) == {"b"}
    assert not (out / "maps/synthetic_box/vp000/a").exists()


def test_summary_text_is_one_row_per_method_best_first_and_never_drops_a_missing_metric():
    rows = [{"scene": "s", "viewpoint": v, "method": m, "flow": "", "rectify": "", "variant": "", "mae_m": x,
             "median_m": x / 2, "delta110": 0.5, "seconds": 2.0, "floor_m": 0.05, "mae_x_floor": x / 0.05}
            for m, v, x in (("m", "vp0", 1.0), ("m", "vp1", float("nan")), ("good", "vp0", 0.25), ("good", "vp1", 0.75),
                            ("bad", "vp0", 3.0))]
    lines = summary_text(pd.DataFrame(rows)).splitlines()
    assert lines[0].split() == ["method", "frames", "MAE", "(m)", "x", "floor", "median", "(m)", "delta<1.10",
                                "s/frame"]
    assert [line.split()[:3] for line in lines[1:]] == [["good", "2", "0.5000"], ["bad", "1", "3.0000"],
                                                        ["m", "2", "-"]]  # a NaN frame: no mean, shown last
    assert lines[1].split()[3:] == ["10.00", "0.2500", "50.0", "%", "2.0"]  # x floor: mean of 5 and 15
    assert lines[3].split()[3] == "-"
    assert "nan" not in "\n".join(lines).lower() and len({len(line) for line in lines}) == 1  # aligned


@pytest.mark.slow
def test_every_scored_row_carries_the_frames_floor(synthetic_root, tmp_path):
    """results.csv and regions.csv: floor_m is the frame's floor over the row's pixels (the same for every method of
    a frame, per region too) and mae_x_floor = mae_m / floor_m; the summary prints the mean multiple."""
    out = tmp_path / "res"
    methods = [Constant(2.0, "two"), Constant(3.0, "three")]
    table = evaluate(synthetic_root, out, methods, report=False, ctx=QUIET)
    regions_csv = read_regions(out)
    for vp in ("vp000", "vp001"):
        frame = read_frame(synthetic_root / "synthetic_box" / vp)
        sigma = frame_floor_sigma(frame)
        floors = region_floors(sigma, regions(frame))
        assert floors["all"] == pytest.approx(floor_mae(sigma), rel=1e-12)
        assert 0 < floors["all"] < 0.1  # metres: a 200x100 box room a few metres across, 0.25 px
        rows = table[table.viewpoint == vp]
        np.testing.assert_allclose(rows.floor_m, floors["all"], rtol=1e-12)  # the same for every method
        np.testing.assert_allclose(rows.mae_x_floor, rows.mae_m / floors["all"], rtol=1e-12)
        for _, r in regions_csv[regions_csv.viewpoint == vp].iterrows():
            want = floors[r.region]
            assert r.floor_m == pytest.approx(want, rel=1e-9, nan_ok=True), r.region  # CSV round trip
            assert r.mae_x_floor == pytest.approx(r.mae_m / want, rel=1e-9, nan_ok=True), r.region
    assert regions_csv.floor_m.notna().sum() > len(regions_csv) / 2  # most regions hold pixels here
    on_disk = read_results(out)
    np.testing.assert_allclose(on_disk.floor_m, table.floor_m, rtol=1e-9)
    summary = summary_text(table).splitlines()
    two = next(line for line in summary if line.startswith("two")).split()
    assert two[3] == f"{table[table.method == 'two'].mae_x_floor.mean():.2f}"


@pytest.mark.slow
def test_progress_bar_names_frame_and_methods(synthetic_root, tmp_path, capsys):
    """The bar's postfix names the task (``scene/viewpoint first-method +N``), not an index tuple."""
    evaluate(synthetic_root, tmp_path / "res", [Constant(1.0, "a"), Constant(2.0, "b")], report=False, ctx=RunContext())
    err = capsys.readouterr().err
    assert "synthetic_box/vp000 a +1" in err and "(0, 0)" not in err
