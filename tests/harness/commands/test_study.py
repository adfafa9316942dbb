"""``tri360 study``: a grid of render/evaluate settings in one command, on a Dask scheduler or in this process;
frames and results are reused when the study is rerun or extended."""

from __future__ import annotations

import dataclasses
import json
import os
import time
from pathlib import Path

import pandas as pd
import pytest
from distributed import Client
from distributed.diagnostics.plugin import WorkerPlugin

from harness.cli import main
from harness.commands.render import plan_render
from harness.commands.study import grid_points, load_study, point_ids, run_study
from harness.data.errors import UserError
from harness.render.base import RenderSettings
from harness.runtime.context import QUIET
from reconstruction.methods.registry import get_methods
from tests.helpers import wait_for_workers

PNG = b"\x89PNG\r\n\x1a\n"

STUDY = """
[render]
scene = "synthetic_box"
width = 200
viewpoints = 1

[evaluate]
method = ["dis-rect:gradient", "dis-rect:average"]

[grid]
baseline = {values}
"""


def write_study(path: Path, values: list) -> Path:
    path.write_text(STUDY.format(values=json.dumps(values)), encoding="utf-8")
    return path


def mtimes(root: Path, name: str) -> dict:
    return {p: p.stat().st_mtime_ns for p in root.rglob(name)}


@pytest.fixture
def scheduler(dask_cluster):
    """The shared cluster's address, both workers up now."""
    wait_for_workers(dask_cluster.address, 2)
    return dask_cluster.address


class Barrier(WorkerPlugin):
    """Holds each task of ``prefix`` at its start until ``n`` of them, on different workers, have started
    (files in ``directory``), for at most ``timeout_s``: tasks that run at the same time pass it, tasks run one
    after another cannot.  Proves concurrency without comparing wall-clock times; a timeout leaves a file
    ``timeout-<pid>`` and lets the task go on (so the test fails on it instead of hanging)."""

    def __init__(self, directory: str, prefix: str, n: int, timeout_s: float = 120.0):
        self.directory, self.prefix, self.n, self.timeout_s = directory, prefix, n, timeout_s

    def transition(self, key, start, finish, **kwargs):
        if finish != "executing" or not str(key).startswith(self.prefix):
            return
        d = Path(self.directory)
        (d / f"arrived-{os.getpid()}").touch()
        deadline = time.monotonic() + self.timeout_s
        while len(list(d.glob("arrived-*"))) < self.n:
            if time.monotonic() > deadline:
                (d / f"timeout-{os.getpid()}").touch()
                return
            time.sleep(0.05)


@pytest.mark.cluster
def test_study_on_a_scheduler_writes_csv_plot_and_summary(scheduler, tmp_path, capsys):
    study = write_study(tmp_path / "baseline.toml", [0.2, 0.4])
    out = tmp_path / "study"
    barrier = tmp_path / "barrier"
    barrier.mkdir()
    # the plugin lives on the scheduler; this client is closed before the study's own client runs (two clients in one
    # process clashed now and then: "bound to a different event loop")
    with Client(scheduler, timeout=30) as c:
        c.register_plugin(Barrier(str(barrier), "tri360_render-", n=2), name="barrier")
    try:
        assert main(["study", str(study), "--out", str(out), "--scheduler", scheduler, "--quiet"]) == 0
    finally:
        with Client(scheduler, timeout=30) as c:
            c.unregister_worker_plugin("barrier")
    # the two points (one frame each) were rendered at the same time, by both workers: each render waited at
    # its start for the other's
    assert len(list(barrier.glob("arrived-*"))) == 2 and not list(barrier.glob("timeout-*")), \
        sorted(p.name for p in barrier.iterdir())
    table = pd.read_csv(out / "study.csv")
    assert list(table.columns[:3]) == ["baseline", "scene", "viewpoint"]
    assert {"mae_m", "rmse_m", "method", "render_s"} <= set(table.columns)
    assert len(table) == 2 * 1 * 2  # grid points x frames x methods
    assert sorted(table.baseline.unique()) == [0.2, 0.4]
    assert not table.duplicated(["baseline", "scene", "viewpoint", "method"]).any()
    assert (table.mae_m > 0).all() and (table.mae_m < 0.5).all()  # metres, a sane synthetic-box error
    # each grid point's frames were rendered with its baseline
    for point in json.loads((out / "points.json").read_text()):
        (meta,) = (out / point["data"]).rglob("frame.json")
        assert json.loads(meta.read_text())["baseline_m"] == pytest.approx(point["grid"]["baseline"])
    assert (out / "baseline.png").read_bytes().startswith(PNG)
    md = (out / "study.md").read_text()
    assert "baseline.png" in md and "dis-rect:gradient" in md and "| 0.4 |" in md
    with Client(scheduler, timeout=30) as c:
        prefixes = c.run_on_scheduler(lambda dask_scheduler: sorted(dask_scheduler.task_prefixes))
    assert {"tri360_render", "tri360_evaluate"} <= set(prefixes)
    logs = [json.loads(p.read_text()) for p in sorted((out / "data").rglob("render_log.json"))]
    assert len(logs) == 2 and logs[0]["pid"] != logs[1]["pid"]
    assert {f"arrived-{g['pid']}" for g in logs} == {p.name for p in barrier.glob("arrived-*")}

    # rerun: nothing rendered or evaluated again
    frames, results = mtimes(out / "data", "frame.json"), mtimes(out / "results", "results.csv")
    assert main(["study", str(study), "--out", str(out), "--quiet"]) == 0
    assert mtimes(out / "data", "frame.json") == frames and mtimes(out / "results", "results.csv") == results
    pd.testing.assert_frame_equal(pd.read_csv(out / "study.csv"), table)

    # extended grid: only the new point is rendered and evaluated
    write_study(study, [0.2, 0.4, 0.6])
    assert main(["study", str(study), "--out", str(out), "--quiet"]) == 0
    assert mtimes(out / "data", "frame.json").items() >= frames.items()
    assert len(mtimes(out / "data", "frame.json")) == 3
    assert mtimes(out / "results", "results.csv").items() >= results.items()
    extended = pd.read_csv(out / "study.csv")
    assert len(extended) == 6 and sorted(extended.baseline.unique()) == [0.2, 0.4, 0.6]
    pd.testing.assert_frame_equal(extended.iloc[:4].drop(columns="seconds"), table.drop(columns="seconds"))


@pytest.mark.slow
def test_a_change_of_render_defaults_gives_new_data_roots():
    """Frames rendered under other defaults are never reused (nor refused): the point gets a new data root; a
    setting that changes no pixel (threads) keeps the data root."""
    methods = get_methods(["fused"])

    def ids(settings, methods=methods, **kw):
        return point_ids(plan_render(settings, "classroom", place_rigs=False, **kw), methods, False)

    rid, eid = ids(RenderSettings(width=500))
    assert rid.startswith("r-") and eid.startswith("e-") and ids(RenderSettings(width=500)) == (rid, eid)
    old = dataclasses.replace(RenderSettings(width=500), samples=12, light_tree=True)
    assert ids(old)[0] != rid and ids(old)[1] != eid
    assert ids(RenderSettings(width=500), get_methods(["sweep"]))[0] == rid  # the methods do not change frames
    assert ids(RenderSettings(width=500), get_methods(["sweep"]))[1] != eid
    assert ids(RenderSettings(width=1000))[0] != rid
    assert ids(RenderSettings(width=500, threads=1)) == (rid, eid)  # threads change no pixel
    assert ids(RenderSettings(width=500), viewpoints=2)[0] != rid


@pytest.mark.slow
def test_two_grid_keys_run_the_full_product(tmp_path):
    study = tmp_path / "two.toml"
    study.write_text("""
[render]
scene = "synthetic_box"
width = 128

[evaluate]
flow = "dis"

[grid]
baseline = [0.3, 0.5]
variants = [["average"], ["gradient", "angle"]]
""", encoding="utf-8")
    spec = load_study(study)
    assert grid_points(spec) == [{"baseline": 0.3, "variants": ["average"]},
                                 {"baseline": 0.3, "variants": ["gradient", "angle"]},
                                 {"baseline": 0.5, "variants": ["average"]},
                                 {"baseline": 0.5, "variants": ["gradient", "angle"]}]
    table = run_study(study, tmp_path / "out", ctx=QUIET)
    assert len(table) == 2 * (1 + 2)  # baselines x methods of each variants value, one frame
    assert len(list((tmp_path / "out" / "data").iterdir())) == 2  # one data root per baseline, shared by variants
    assert len(list((tmp_path / "out" / "results").iterdir())) == 4
    for key in ("baseline", "variants"):
        assert (tmp_path / "out" / f"{key}.png").read_bytes().startswith(PNG)
    assert set(table.method) == {"dis-rect:average", "dis-rect:gradient", "dis-rect:angle"}


@pytest.mark.parametrize(("text", "message"), [
    ("[render]\nwidht = 200\n", "unknown key(s) widht"),
    ("[grid]\nbaseline = 0.2\n", "must be a non-empty list"),
    ("[grid]\nnope = [1]\n", "no render or evaluate option"),
    ("[sweep]\n", "unknown section"),
    ("[render\n", "not valid TOML"),
    ("[grid]\nbaseline = [0.2, 0.2]\n", "lists a value twice"),
    ("[evaluate]\nmethod = ['nope:gradient']\n", "nope"),
    ("[render]\nscene = 'synthetic_box'\nwidth = 64\nlight_tree = 'yes'\n",
     "light_tree: expected true or false, got 'yes'"),
])
def test_bad_study_files_are_one_line_errors(tmp_path, capsys, text, message):
    study = tmp_path / "bad.toml"
    study.write_text(text, encoding="utf-8")
    assert main(["study", str(study), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err, err
    assert not (tmp_path / "out" / "data").exists()


def test_missing_study_file(tmp_path):
    with pytest.raises(UserError, match="does not exist"):
        run_study(tmp_path / "none.toml", tmp_path / "out")
    assert not os.path.exists(tmp_path / "out")


def test_shipped_studies_parse():
    root = Path(__file__).resolve().parents[3] / "studies"
    expected = {"baseline.toml": "baseline", "resolution.toml": "width", "samples.toml": "samples"}
    for name, key in expected.items():
        spec = load_study(root / name)
        assert key in spec.grid and len(spec.grid[key]) >= 3


@pytest.mark.slow
def test_grid_keys_that_are_results_columns(tmp_path):
    """width is also a results column (the same value: one column); method is too (a list of labels per point:
    its own column, grid_method)."""
    study = tmp_path / "cols.toml"
    study.write_text("""
[render]
scene = "synthetic_box"

[grid]
width = [128, 160]
method = [["dis-rect:average"], ["oracle-rect:average"]]
""", encoding="utf-8")
    table = run_study(study, tmp_path / "out", ctx=QUIET)
    assert list(table.columns[:2]) == ["width", "grid_method"] and list(table.columns).count("width") == 1
    assert len(table) == 4 and sorted(table.width.unique()) == [128, 160]
    assert set(table.method) == {"dis-rect:average", "oracle-rect:average"}
    assert (tmp_path / "out" / "width.png").is_file() and (tmp_path / "out" / "method.png").is_file()
