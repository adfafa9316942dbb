"""Study files are typed: every key of [render], [evaluate] and [grid] is checked against its option's type and
range, and every grid point is checked, before anything is written or rendered; a large plan says its size and
needs --yes; a threads-only change reuses the frames; a study's mismatch error says what to do."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import harness.commands.study as study_job
from harness.cli import main
from harness.commands.parts.robustness import is_robustness_study, load_robustness
from harness.commands.study import load_study, run_study
from harness.data.errors import UserError
from harness.runtime.context import QUIET
from harness.runtime.options import typed_value
from tests.helpers import render_scene

TINY = '[render]\nscene = "synthetic_box"\nwidth = 64\n[evaluate]\nmethod = ["oracle-rect:average"]\n'
"""A valid one-point study (one 64 px ray-cast frame, the oracle)."""


BASE = {"render": {"scene": '"synthetic_box"', "width": "64"}, "evaluate": {"method": '["oracle-rect:average"]'},
        "grid": {}}


def study_text(change: dict) -> str:
    """BASE with ``change`` ({section: {key: TOML value or None to drop}}) applied, as TOML text."""
    sections = {name: dict(keys) for name, keys in BASE.items()}
    for name, keys in change.items():
        for key, value in keys.items():
            if value is None:
                sections[name].pop(key, None)
            else:
                sections[name][key] = value
    return "".join(f"[{name}]\n" + "".join(f"{k} = {v}\n" for k, v in keys.items()) for name, keys in sections.items())


R, E, G = "render", "evaluate", "grid"


@pytest.mark.parametrize(("change", "message"), [
    # booleans are TOML booleans
    ({R: {"no_denoise": '"false"'}}, "[render] no_denoise: expected true or false, got 'false'"),
    ({E: {"report": '"false"'}}, "[evaluate] report: expected true or false, got 'false'"),
    ({E: {"method": None, "rectify": "1"}}, "[evaluate] rectify: expected true or false, got 1"),
    ({R: {"light_tree": '"yes"'}}, "light_tree: expected true or false"),
    ({G: {"no_denoise": '[false, "true"]'}}, "[grid] no_denoise[1]: expected true or false"),
    # integers are integers
    ({R: {"width": "128.0"}}, "[render] width: expected an integer, got 128.0"),
    ({R: {"width": '"abc"'}}, "[render] width: expected an integer, got 'abc'"),
    ({R: {"viewpoints": '"2"'}}, "[render] viewpoints: expected an integer, got '2'"),
    ({R: {"samples": "true"}}, "[render] samples: expected an integer, got True"),
    ({G: {"seed": "[0, 0.0]"}}, "[grid] seed[1]: expected an integer, got 0.0"),
    ({R: {"baseline": '"0.4"'}}, "[render] baseline: expected a number, got '0.4'"),
    ({R: {"baseline": "nan"}}, "[render] baseline: expected a number, got nan"),
    # strings, lists of strings, tables
    ({E: {"method": "5"}}, "[evaluate] method: expected a string or a non-empty list of strings, got 5"),
    ({E: {"method": "[]"}}, "[evaluate] method: expected a string or a non-empty list of strings"),
    ({E: {"method": None, "flow": '"dis"'}, G: {"variants": "[['average'], [3]]"}},
     "[grid] variants[1]: expected a string or a non-empty list"),
    ({R: {"scene": "3"}}, "[render] scene: expected a string, got 3"),
    ({R: {"set": "5"}}, "[render] set: expected a table or a string or a non-empty list of strings, got 5"),
    ({R: {"set": '["jitter_m"]'}}, "[render] set expects KEY=VALUE, got 'jitter_m'"),
    # ranges and names, for every grid point, before the first render
    ({G: {"width": "[128, 61]"}}, "(grid point {'width': 61}): --width must be an even number"),
    ({G: {"width": "[128, 58]"}}, "(grid point {'width': 58}): --width must be >= 60"),
    ({G: {"baseline": "[0.2, -1.0]"}}, "(grid point {'baseline': -1.0}): --baseline must be a positive"),
    ({G: {"viewpoints": "[1, 0]"}}, "--viewpoints must be >= 1"),
    ({G: {"samples": "[4, 0]"}}, "--samples must be >= 1"),
    ({G: {"threads": "[1, -1]"}}, "--threads must be >= 0"),
    ({R: {"renderer": '"nope"'}}, "unknown renderer 'nope'"),
    ({R: {"set": "{rooom = 1}"}}, "rooom: expected one of the keys room, furniture"),
    ({G: {"scene": '["synthetic_box", "nope"]'}}, "nope"),
    ({G: {"method": "[['oracle-rect:average'], ['nope:x']]"}}, "unknown method(s) nope:x"),
    ({E: {"flow": '"dis"'}}, "method selects methods by label; do not combine it with flow, rectify or variants"),
    ({E: {"method": None, "flow": '"nope"'}}, "unknown flow 'nope'"),
])
def test_bad_study_files_are_refused_before_any_work(tmp_path, capsys, change, message):
    """One line naming the key (and the grid point), status 2, nothing written."""
    study = tmp_path / "bad.toml"
    study.write_text(study_text(change), encoding="utf-8")
    out = tmp_path / "out"
    assert main(["study", str(study), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err and "Traceback" not in err, err
    assert not out.exists(), "written before the study was checked"


def test_a_huge_grid_is_refused_from_its_lengths_before_planning(tmp_path, capsys, monkeypatch):
    study = tmp_path / "huge.toml"
    study.write_text(TINY + f"[grid]\nseed = {list(range(100))}\nbaseline = {[0.2 + i / 1000 for i in range(100)]}\n",
                     encoding="utf-8")
    planned = []
    monkeypatch.setattr("harness.commands.study.plan_point", lambda *a, **k: planned.append(a))
    assert main(["study", str(study), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    assert planned == []  # refused from the grid's lengths, before any point was planned
    err = capsys.readouterr().err.strip()
    assert "10000 grid points (100 seed x 100 baseline)" in err and "--yes" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_a_plan_past_the_frame_limit_says_its_size_and_needs_yes(tmp_path, capsys):
    study = tmp_path / "many.toml"
    study.write_text(TINY.replace("width = 64", "width = 64\nviewpoints = 3")
                     + f"[grid]\nseed = {list(range(40))}\n", encoding="utf-8")
    assert main(["study", str(study), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "40 grid point(s), 120 frame(s) to render (about" in err and "pass --yes" in err, err
    assert len(err.splitlines()) == 1 and not (tmp_path / "out").exists()


@pytest.mark.slow
def test_a_plan_past_the_notice_size_says_frames_and_time_before_it_starts(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(study_job, "NOTICE_FRAMES", 0)
    study = tmp_path / "one.toml"
    study.write_text(TINY, encoding="utf-8")
    run_study(study, tmp_path / "out", ctx=QUIET)
    first = capsys.readouterr().out.splitlines()[0]
    assert first.startswith("study: 1 grid point(s), 1 frame(s) to render (about ") and "1 evaluation(s)" in first
    run_study(study, tmp_path / "out", ctx=QUIET)  # a rerun renders nothing: no notice
    assert capsys.readouterr().out == ""


@pytest.mark.slow
def test_a_threads_only_change_reuses_the_frames(tmp_path):
    study = tmp_path / "threads.toml"
    study.write_text(TINY + "[grid]\nthreads = [1, 2]\n", encoding="utf-8")
    table = run_study(study, tmp_path / "out", ctx=QUIET)
    assert len(table) == 2
    (root,) = (tmp_path / "out" / "data").iterdir()  # one data root: threads change no pixel
    assert len(list(root.rglob("frame.json"))) == 1
    points = json.loads((tmp_path / "out" / "points.json").read_text())
    assert points[0]["data"] == points[1]["data"]


@pytest.mark.slow
def test_a_study_mismatch_says_what_to_do_not_force(tmp_path, capsys):
    study = tmp_path / "one.toml"
    study.write_text(TINY, encoding="utf-8")
    run_study(study, tmp_path / "out", ctx=QUIET)
    (meta,) = (tmp_path / "out" / "data").rglob("frame.json")
    frame = json.loads(meta.read_text())
    frame["renderer"]["scene"]["code_version"] = "sha256:0000"  # as if an older tri360 had rendered it
    meta.write_text(json.dumps(frame))
    assert main(["study", str(study), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "other settings" in err and "scene code version" in err, err
    assert "--force" not in err and "remove that directory" in err


def test_typed_values_from_annotations():
    assert typed_value(1, float, "x") == 1.0 and isinstance(typed_value(1, float, "x"), float)
    assert typed_value("a", tuple[str, ...], "x") == ("a",) and typed_value(["a", "b"], tuple[str, ...], "x") == (
        "a", "b")
    assert typed_value(True, bool | None, "x") is True
    for value, hint in [(1, bool), (True, int), (1.5, int), ("1", int), (float("inf"), float), ([], tuple[str, ...]),
                        ({"a": 1}, str)]:
        with pytest.raises(UserError, match="^x: expected "):
            typed_value(value, hint, "x")


@pytest.mark.slow
def test_shipped_studies_are_typed_and_valid():
    root = Path(__file__).resolve().parents[3] / "studies"
    for path in sorted(root.glob("*.toml")):
        if is_robustness_study(path):  # kind = "robustness": its own format (tests/harness/commands/test_robustness.py)
            load_robustness(path)
            continue
        spec = load_study(path)
        for point in study_job.grid_points(spec):
            study_job.plan_point(spec, point)


def test_settings_type_errors_are_one_line_for_library_callers(tmp_path):
    with pytest.raises(UserError, match="^width: expected an integer, got 128.0$"):
        render_scene("synthetic_box", out_root=tmp_path, width=128.0, ctx=QUIET)
    assert not any(tmp_path.iterdir())
