"""Every built-in method's configuration is the reviewed snapshot ``presets_snapshot.json`` beside this file
(tools/presets_snapshot.py; rewrite it on purpose with ``python -m tools.presets_snapshot --update`` or
``make presets-update`` and review its diff), and a difference is one readable line per key."""

from __future__ import annotations

import copy
import json

import pytest

from reconstruction.methods.registry import ABLATIONS, PRESETS, builtin_methods
from tools import presets_snapshot as ps


def test_every_builtin_methods_configuration_is_the_reviewed_snapshot():
    problems = ps.differences(ps.load(), ps.compute())
    assert not problems, "\n".join([*problems, f"if these changes are meant, rewrite the snapshot: {ps.UPDATE_COMMAND}"
                                                " (make presets-update) and review its diff"])


def test_the_snapshot_covers_every_builtin_method_presets_first():
    labels = list(ps.compute())
    assert labels == [m.label for m in builtin_methods()]  # no outside plugin is installed in the test run
    assert labels[:len(PRESETS) + len(ABLATIONS)] == [p.label for p in (*PRESETS, *ABLATIONS)]


@pytest.fixture
def live():
    """Two small configurations, as JSON."""
    return {"a": {"kind": "x", "cost": {"weight": 0.25, "levels": 160, "on": True}, "pairs": ["U", "R"]},
            "b": {"kind": "x", "cost": {"weight": 0.25, "levels": 160, "on": True}, "pairs": ["U", "R"]}}


def test_a_changed_value_is_one_line_naming_method_path_and_both_values(live):
    stored = copy.deepcopy(live)
    stored["a"]["cost"]["weight"] = 0.5
    stored["b"]["pairs"][1] = "L"
    assert ps.differences(stored, live) == ["[a] cost.weight: 0.5 in the snapshot, 0.25 live",
                                            "[b] pairs[1]: \"L\" in the snapshot, \"R\" live"]
    assert ps.differences(live, copy.deepcopy(live)) == []


def test_methods_that_differ_alike_share_a_line(live):
    stored = copy.deepcopy(live)
    for label in stored:
        stored[label]["cost"]["levels"] = 128
    (line,) = ps.differences(stored, live)
    assert line == "[a, b] cost.levels: 128 in the snapshot, 160 live"
    many = {f"m{i}": copy.deepcopy(live["a"]) for i in range(6)}
    stored = copy.deepcopy(many)
    for cfg in stored.values():
        cfg["kind"] = "y"
    assert ps.differences(stored, many) == ["[m0, m1, m2, m3, +2 more] kind: \"y\" in the snapshot, \"x\" live"]


def test_missing_and_added_keys_and_methods_are_named(live):
    stored = copy.deepcopy(live)
    del stored["a"]["cost"]["on"]
    stored["a"]["old"] = 1
    stored["c"] = stored.pop("b")
    assert ps.differences(stored, live) == [
        "[a] cost.on: absent in the snapshot, true live",
        "[a] old: 1 in the snapshot, absent live",
        "[c] is in the snapshot but is no built-in method",
        "[b] is a built-in method missing from the snapshot"]


def test_types_count_an_int_is_not_a_float_nor_a_bool(live):
    stored = copy.deepcopy(live)
    stored["a"]["cost"]["levels"] = 160.0
    stored["a"]["cost"]["on"] = 1
    assert ps.differences(stored, live) == ["[a] cost.levels: 160.0 in the snapshot, 160 live",
                                            "[a] cost.on: 1 in the snapshot, true live"]


def test_a_long_value_is_cut(live):
    stored = copy.deepcopy(live)
    stored["a"]["pairs"] = ["x" * 200]
    (line,) = ps.differences(stored, live)
    shown = line.split(": ", 1)[1].split(" in the snapshot")[0]
    assert len(shown) == ps.SHOWN_CHARS and shown.endswith("...")


def test_the_file_reads_back_every_float_exactly(tmp_path):
    floats = [0.1 + 0.2, 1 / 3, 2.0 ** -1074, 1.7976931348623157e308, 4.685, 1e-7]
    path = tmp_path / "snapshot.json"
    ps.update(path, {"m": {"values": floats, "n": 3}})
    (values,) = [cfg["values"] for cfg in ps.load(path).values()]
    assert [v.hex() for v in values] == [v.hex() for v in floats]
    assert ps.differences(ps.load(path), {"m": {"values": floats, "n": 3}}) == []


def test_a_value_that_is_not_json_is_refused_naming_its_method():
    class Infinite:
        label = "far"

        def config(self):
            return {"d_max_m": float("inf")}

    with pytest.raises(ValueError, match="^the configuration of far is not JSON"):
        ps.compute([Infinite()])


def test_update_replaces_only_a_snapshot_file(tmp_path):
    other = tmp_path / "results.json"
    other.write_text(json.dumps({"scene": "x"}))
    with pytest.raises(ValueError, match="not a presets snapshot"):
        ps.update(other, {"m": {}})
    assert json.loads(other.read_text()) == {"scene": "x"}
    with pytest.raises(ValueError, match="its folder does not exist"):
        ps.update(tmp_path / "missing" / "s.json", {"m": {}})


def test_the_command_checks_and_rewrites(tmp_path, capsys, monkeypatch):
    live = {"a": {"weight": 0.25}}
    monkeypatch.setattr(ps, "compute", lambda: live)
    path = tmp_path / "snapshot.json"
    assert ps.main(["--file", str(path)]) == 2
    assert f"no presets snapshot (write it with `{ps.UPDATE_COMMAND}`)" in capsys.readouterr().err
    assert ps.main(["--file", str(path), "--update"]) == 0 and ps.load(path) == live
    assert ps.main(["--file", str(path)]) == 0
    live["a"]["weight"] = 0.5
    assert ps.main(["--file", str(path)]) == 1
    err = capsys.readouterr().err
    assert "[a] weight: 0.25 in the snapshot, 0.5 live" in err and ps.UPDATE_COMMAND in err
