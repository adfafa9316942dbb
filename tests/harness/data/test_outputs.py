"""Outputs replace only what tri360 wrote, and names never become paths outside ``--out``.

For every command that writes (render, reconstruct, evaluate, score, report, study), ``--out`` pointed at the data
root, at its parent, at a predictions root and at a directory holding a user's file is refused with exit status 2
and one line naming the path, and nothing is deleted or changed: every file under the test directory is the same,
byte for byte, before and after.  Then the one shared check (``harness.data.outputs``) and the one name rule
(``harness.data.names``) on their own.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from harness.cli import main
from harness.commands.evaluate import evaluate
from harness.data.errors import UserError
from harness.data.names import check_name, is_safe_name
from harness.data.outputs import MARKER, check_output, foreign_entries, mark_output, output_kind, read_marker
from harness.data.predictions import write_method_info, write_prediction
from harness.runtime.context import QUIET
from reconstruction.methods.base import MethodOutput

RENDER = ("render", "--scene", "synthetic_box", "--width", "64", "--quiet")
METHOD = ("--flow", "oracle", "--variants", "average")


def run(argv: list[str]) -> int:
    try:
        return main([str(a) for a in argv])
    except SystemExit as exc:  # argparse
        return exc.code if isinstance(exc.code, int) else 1


def contents(root: Path) -> dict[str, bytes | str]:
    """Every entry under ``root``: directories as "dir", links as their target, files by their bytes."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for n in dirnames + filenames:
            p = Path(dirpath) / n
            rel = str(p.relative_to(root))
            out[rel] = ("link:" + os.readlink(p)) if p.is_symlink() else ("dir" if p.is_dir() else p.read_bytes())
    return out


@pytest.fixture(scope="module")
def template(tmp_path_factory) -> Path:
    """work/: data/ (rendered by `tri360 render`), preds/ (`tri360 reconstruct`), results/ (`tri360 evaluate`),
    user/notes.txt (a user's directory) and study.toml."""
    t = tmp_path_factory.mktemp("outputs") / "work"
    t.mkdir()
    assert run([*RENDER, "--out", t / "data"]) == 0
    frame = t / "data" / "synthetic_box" / "vp000"
    assert run(["reconstruct", frame, "--out", t / "preds", "--flow", "oracle", "--variant", "average",
                "--quiet"]) == 0
    assert run(["evaluate", t / "data", "--out", t / "results", *METHOD, "--no-report", "--quiet"]) == 0
    (t / "user").mkdir()
    (t / "user" / "notes.txt").write_text("my thesis notes\n")
    (t / "study.toml").write_text('[render]\nscene = "synthetic_box"\nwidth = 64\n\n[evaluate]\n'
                                  'method = ["oracle-rect:average"]\n\n[grid]\nseed = [0, 1]\n')
    return t


@pytest.fixture()
def work(tmp_path, template) -> Path:
    w = tmp_path / "work"
    shutil.copytree(template, w, symlinks=True)
    return w


def command(name: str, w: Path, out: Path) -> list:
    frame = w / "data" / "synthetic_box" / "vp000"
    return {
        "render": [*RENDER, "--out", out],
        "reconstruct": ["reconstruct", frame, "--out", out, "--flow", "oracle", "--variant", "gradient", "--quiet"],
        "evaluate": ["evaluate", w / "data", "--out", out, *METHOD, "--no-report", "--quiet"],
        "score": ["score", w / "preds", "--data", w / "data", "--out", out, "--no-report", "--quiet"],
        "report": ["report", out, "--ply", "none"],
        "study": ["study", w / "study.toml", "--out", out, "--quiet"],
    }[name]


TARGETS = {
    "data-root": lambda w: w / "data",
    "parent-of-data-root": lambda w: w,
    "frame-dir": lambda w: w / "data" / "synthetic_box" / "vp000",
    "predictions-root": lambda w: w / "preds",
    "users-directory": lambda w: w / "user",
    "link-to-data-root": lambda w: w / "link",
}
WRITERS = ("render", "reconstruct", "evaluate", "score", "report", "study")
# render writes a data root: pointing it at one is a rerun into its own kind (tested below, not refused)
REFUSALS = [(c, t) for c in WRITERS for t in TARGETS if not (c == "render" and t in ("data-root",
                                                                                  "link-to-data-root"))]


@pytest.mark.parametrize(("cmd", "target"), REFUSALS, ids=[f"{c}-{t}" for c, t in REFUSALS])
def test_out_that_is_not_an_output_of_the_kind_is_refused_and_nothing_changes(cmd, target, work, capfd):
    (work / "link").symlink_to(work / "data")
    out = TARGETS[target](work)
    before = contents(work)
    capfd.readouterr()
    code = run(command(cmd, work, out))
    o, e = capfd.readouterr()
    lines = [x for x in e.splitlines() if x.strip()]
    assert code == 2, e
    assert len(lines) == 1 and lines[0].startswith(f"tri360 {cmd}: error: {out}"), lines
    assert "Traceback" not in o + e
    assert contents(work) == before, "a refused command changed or deleted files"


def test_users_file_is_named_with_the_count(work, capfd):
    (work / "user" / "more.txt").write_text("x")
    assert run(command("evaluate", work, work / "user")) == 2
    err = capfd.readouterr().err
    assert "2 entries not written by tri360, e.g. more.txt" in err, err


def test_a_results_set_with_a_users_file_is_refused_by_evaluate_score_and_report(work, capfd):
    (work / "results" / "notes.txt").write_text("mine")
    before = contents(work)
    for cmd in ("evaluate", "score", "report"):
        assert run(command(cmd, work, work / "results")) == 2
        assert "notes.txt" in capfd.readouterr().err
    assert contents(work) == before


@pytest.mark.slow
@pytest.mark.parametrize("legacy", [False, True], ids=["marked", "legacy-without-marker"])
def test_reruns_into_the_same_kind_are_accepted(work, legacy, capfd):
    """make evaluate's two commands rerun, also on outputs of the previous release (no marker)."""
    if legacy:
        for d in ("data", "preds", "results"):
            (work / d / MARKER).unlink()
    frames = contents(work / "data")
    assert run(command("render", work, work / "data")) == 0
    assert {k: v for k, v in contents(work / "data").items() if k != MARKER} == \
        {k: v for k, v in frames.items() if k != MARKER}  # the frames are kept as they were
    assert run(command("evaluate", work, work / "results")) == 0
    assert run(command("report", work, work / "results")) == 0
    assert (work / "results" / "report.html").is_file()
    assert run(["reconstruct", work / "data" / "synthetic_box" / "vp000", "--out", work / "preds", "--flow",
                "oracle", "--variant", "average", "--quiet"]) == 0
    for d, kind in (("data", "data"), ("preds", "predictions"), ("results", "results")):
        assert read_marker(work / d)["kind"] == kind


def test_evaluate_into_absent_and_empty_directories(work):
    (work / "empty").mkdir()
    for out in (work / "empty", work / "new" / "deeper"):
        assert run(command("evaluate", work, out)) == 0
        assert read_marker(out)["kind"] == "results"
        assert set(read_marker(out)["entries"]) >= {"results.csv", "config.json", "maps"}


# ------------------------------------------------------------------------------------- one method per root


def test_a_second_method_into_a_predictions_root_is_refused(work, capfd):
    before = contents(work)
    assert run(command("reconstruct", work, work / "preds")) == 2  # gradient into a root of oracle-rect:average
    err = capfd.readouterr().err
    assert f"{work / 'preds'}" in err and "'oracle-rect:average'" in err and len(err.splitlines()) == 1, err
    assert contents(work) == before


def test_predictions_without_method_json_are_not_mixed(work, capfd):
    (work / "preds" / "method.json").unlink()
    assert run(command("reconstruct", work, work / "preds")) == 2
    assert "no method.json" in capfd.readouterr().err


# --------------------------------------------------------------------------------------------------- names


@pytest.mark.parametrize("name", ["../x", "../../escape", "/tmp/abs", "a/b", "..", ".hidden", "", "a b", "x" * 101,
                                  "a\\b", "nul\0"])
def test_score_refuses_unsafe_method_names_and_writes_nothing_anywhere(work, name, capfd, tmp_path):
    before = contents(tmp_path)
    assert run(["score", work / "preds", "--data", work / "data", "--out", work / "res", "--method", name,
                "--no-report", "--quiet"]) == 2
    err = capfd.readouterr().err
    assert "--method" in err and len(err.splitlines()) == 1, err
    assert contents(tmp_path) == before
    assert not Path("/tmp/abs").exists()


def test_score_treats_method_json_as_untrusted(work, capfd, tmp_path):
    info = json.loads((work / "preds" / "method.json").read_text())
    info["name"] = "../../../evil"
    (work / "preds" / "method.json").write_text(json.dumps(info))
    before = contents(tmp_path)
    assert run(command("score", work, work / "res")) == 2
    err = capfd.readouterr().err
    assert str(work / "preds" / "method.json") in err, err
    assert contents(tmp_path) == before


def test_score_checks_a_folder_name_used_as_the_label(work, capfd):
    odd = work / "my preds"
    shutil.copytree(work / "preds", odd)
    (odd / "method.json").unlink()
    assert run(["score", odd, "--data", work / "data", "--out", work / "res", "--no-report", "--quiet"]) == 2
    assert "--method" in capfd.readouterr().err  # says how to name it


class Labelled:
    """A method with a chosen label (as an outside plugin could give), run on a frame -> ground truth."""

    def __init__(self, label):
        self.label = label

    def config(self):
        return {"label": self.label}

    def run(self, frame):
        return MethodOutput(distance=frame.distance["C"], seconds={"total": 0.0})


@pytest.mark.parametrize("label", ["../../outside", "/abs/path", "a/b"])
def test_evaluate_never_writes_a_plugin_label_as_a_path(work, label, tmp_path):
    before = contents(tmp_path)
    with pytest.raises(UserError, match="name"):
        evaluate(work / "data", work / "res", [Labelled(label)], report=False, ctx=QUIET)
    assert contents(tmp_path) == before


def test_two_methods_whose_maps_collide_are_refused(work):
    class Flowish(Labelled):
        flow_name, rectify, variant = "dis", True, "gradient"

    a, b = Flowish("one"), Flowish("two")
    with pytest.raises(UserError, match="same map"):
        evaluate(work / "data", work / "res", [a, b], report=False, ctx=QUIET)


def test_check_name_rule():
    for ok in ("fused", "dis-rect:gradient", "classroom-lecture", "vp000", "a.b", "x=1+2", "A_b", "x" * 100):
        assert check_name(ok, "src") == ok and is_safe_name(ok)
    for bad in ("", ".", "..", "a..b", ".x", "a/b", "a\\b", "/x", "a b", "é", "x" * 101, "a\nb", None, 3):
        assert not is_safe_name(bad)
        with pytest.raises(UserError, match="^src: name"):
            check_name(bad, "src")


# ------------------------------------------------------------------------------------------ the check itself


def test_check_output_kinds_and_content(work):
    assert output_kind(work / "data") == "data" and output_kind(work / "preds") == "predictions"
    assert output_kind(work / "results") == "results" and output_kind(work / "user") is None
    for d in ("data", "preds", "results"):  # recognised by content without a marker too
        (work / d / MARKER).unlink()
    assert output_kind(work / "data") == "data" and output_kind(work / "preds") == "predictions"
    assert output_kind(work / "results") == "results"
    assert foreign_entries(work / "data", "data") == []
    (work / "data" / "synthetic_box" / "vp000" / "notes.txt").write_text("x")
    assert foreign_entries(work / "data", "data") == ["synthetic_box/vp000/notes.txt"]
    with pytest.raises(UserError, match="notes.txt"):
        check_output(work / "data", "data")
    with pytest.raises(UserError, match="is a tri360 predictions root"):
        check_output(work / "preds", "results")
    with pytest.raises(ValueError):
        check_output(work / "x", "bogus")


def test_check_output_compares_real_paths(work, tmp_path):
    (tmp_path / "alias").symlink_to(work)
    for out in (tmp_path / "alias" / "data", tmp_path / "alias", tmp_path / "alias" / "data" / "synthetic_box" / "x"):
        with pytest.raises(UserError, match="input"):
            check_output(out, "results", [work / "data"])
    assert check_output(work / "fresh", "results", [work / "data"]) == work / "fresh"


def test_marker_is_written_atomically_and_left_alone_when_unchanged(work):
    m = work / "results" / MARKER
    before = m.stat().st_mtime_ns, m.read_bytes()
    mark_output(work / "results", "results")
    assert (m.stat().st_mtime_ns, m.read_bytes()) == before
    assert not [p for p in (work / "results").iterdir() if ".partial" in p.name]


def test_a_broken_marker_is_named(work):
    (work / "results" / MARKER).write_text("{")
    with pytest.raises(UserError, match=MARKER):
        check_output(work / "results", "results")


def test_staging_leftovers_and_folder_view_files_do_not_make_a_directory_foreign(work):
    d = work / "empty-ish"
    (d / ".x.partial-1-0000abcd").mkdir(parents=True)
    (d / ".DS_Store").write_bytes(b"\0")
    assert check_output(d, "results") == d
    (work / "results" / "Thumbs.db").write_bytes(b"\0")
    assert check_output(work / "results", "results") == work / "results"


def test_study_out_around_its_own_file_is_refused(work, capfd):
    assert run(["study", work / "study.toml", "--out", work, "--quiet"]) == 2
    assert str(work) in capfd.readouterr().err


def test_prediction_writer_roots_are_marked_for_score_inputs(work):
    """An outside predictions root (no marker, no method.json) is still recognised as predictions."""
    root = work / "outside"
    write_prediction(root, "synthetic_box", "vp000", np.ones((32, 64), np.float32))
    assert output_kind(root) == "predictions"
    write_method_info(root, {"name": "x"})
    assert output_kind(root) == "predictions" and foreign_entries(root, "predictions") == []
