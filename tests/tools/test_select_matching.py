"""The matching selection job: its rule on hand-made tables, and a run on a tiny suite split end to end."""

from __future__ import annotations

import json

import pandas as pd
import pytest

from harness.commands.parts.suite import render_suite
from harness.data.outputs import read_marker
from harness.runtime.context import QUIET
from reconstruction.methods.base import GroupedMethod
from tests.harness.commands.test_suite import MINI, write
from tools.research import select_matching as sel


def table(rows: dict[str, tuple[float, float, float]]) -> pd.DataFrame:
    """method -> (pooled MAE, MAE on family a, MAE on family b), as :func:`sel.family_table` gives them."""
    return pd.DataFrame([{"method": m, "frames": 2, "mae_m": p, "mae_sw_m": p, "mae_family:a": a,
                          "mae_family:b": b, "mae_sw_family:a": a, "mae_sw_family:b": b}
                         for m, (p, a, b) in rows.items()]).set_index("method")


def test_the_rule_takes_the_lowest_pooled_mae_among_methods_never_worse_than_the_better_baseline():
    t = table({"sweep": (0.20, 0.10, 0.30), "fused": (0.18, 0.20, 0.16),
               "good": (0.13, 0.104, 0.16),     # within 5 % of the better baseline on both families
               "better_pooled": (0.11, 0.12, 0.10),  # best overall but 20 % worse than sweep on a
               })
    label, eligible, worst = sel.choose(t)
    assert (label, eligible) == ("good", True)
    assert worst["better_pooled"] == pytest.approx(1.2, abs=1e-9)
    assert worst["sweep"] == pytest.approx(0.30 / 0.16, abs=1e-9)


def test_the_rule_says_when_no_method_meets_the_bound():
    t = table({"sweep": (0.20, 0.10, 0.30), "fused": (0.18, 0.30, 0.10), "x": (0.15, 0.12, 0.12)})
    label, eligible, worst = sel.choose(t)
    assert (label, eligible) == ("x", False)  # the lowest worst ratio (1.2 against 3.0 of both comparison methods)
    with pytest.raises(Exception, match="comparison methods fused"):
        sel.choose(t.drop(index="fused"))


def test_a_candidate_slower_than_fused_over_the_split_is_not_eligible():
    t = table({"sweep": (0.20, 0.10, 0.30), "fused": (0.18, 0.20, 0.16), "slow": (0.12, 0.10, 0.15),
               "quick": (0.13, 0.104, 0.16)})
    t["seconds"] = pd.Series({"sweep": 50.0, "fused": 100.0, "slow": 100.5, "quick": 99.0})
    label, eligible, _ = sel.choose(t)
    assert (label, eligible) == ("quick", True)
    assert sel.choose(t, time_tolerance=0.01)[:2] == ("slow", True)
    assert sel.choose(t, time_tolerance=None)[:2] == ("slow", True)
    text = sel.selection_markdown(t, label, eligible, sel.choose(t)[2], "s", "dev")
    assert "| **quick** | 0.130 | 0.104 | 0.160 | 1.04 | 0.99 |" in text
    assert "| slow | 0.120 | 0.100 | 0.150 | 1.00 | 1.00 |" in text  # 100.5 / 100 rounds to 1.00 but is over


def test_reference_rows_are_never_chosen():
    t = table({"sweep": (0.20, 0.10, 0.30), "fused": (0.18, 0.20, 0.16), "ref": (0.10, 0.09, 0.12),
               "x": (0.15, 0.104, 0.16)})
    assert sel.choose(t, context=["ref"])[:2] == ("x", True)
    assert sel.choose(t, context=[])[:2] == ("ref", True)


def test_candidates_are_sweep_fused_and_the_fused_variants_sharing_one_flow():
    methods = sel.candidate_methods()
    labels = [m.label for m in methods]
    assert labels[:6] == ["sweep", "fused", "sweep-walls", "fused-adaptive", "fused-gated", "fused-mirror"]
    assert len(set(labels)) == len(labels)
    keys = {m.group_key for m in methods if isinstance(m, GroupedMethod)}
    assert len(keys) == 1  # one group: the flow once per frame for every fused candidate


@pytest.mark.slow
def test_candidates_can_be_narrowed_to_the_chosen_one_and_the_comparison_methods(tmp_path, capsys):
    assert [m.label for m in sel.candidate_methods(["fused-gated"])] == ["sweep", "fused", "fused-gated"]
    assert [m.label for m in sel.candidate_methods(["fused"])] == ["sweep", "fused"]
    with pytest.raises(Exception, match=r"unknown candidate\(s\) nope \(candidates: sweep, fused, sweep-walls"):
        sel.candidate_methods(["fused-adaptive", "nope"])
    out = tmp_path / "sel"
    assert sel.main([str(tmp_path), "--out", str(out), "--candidates", "nope", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown candidate(s) nope" in err[0] and not out.exists()


@pytest.mark.slow
def test_select_on_a_tiny_suite_split_writes_the_results_and_the_choice(tmp_path, capsys):
    suite = write(tmp_path, MINI.format(width=64))
    root = tmp_path / "data"
    render_suite(suite, "dev", root, ctx=QUIET)
    out = tmp_path / "sel"
    assert sel.main([str(root), "--suite", str(suite), "--out", str(out), "--quiet"]) == 0
    printed = capsys.readouterr().out
    chosen = json.loads((out / "selection.json").read_text())
    assert chosen["split"] == "dev" and chosen["suite_id"].startswith("sha256:")
    assert chosen["chosen"] in [m.label for m in sel.candidate_methods()]
    assert set(chosen["table"]) == {m.label for m in sel.candidate_methods()} | set(sel.CONTEXT_METHODS)
    assert chosen["chosen"] not in sel.CONTEXT_METHODS and chosen["time_tolerance"] == sel.TIME_TOLERANCE
    assert all(chosen["table"][m]["seconds"] > 0 for m in chosen["table"])
    assert f"**{chosen['chosen']}**" in (out / "selection.md").read_text() and "Chosen:" in printed
    assert {"selection.md", "selection.json", "results.csv"} <= set(read_marker(out)["entries"])
    # a rerun into its own output is accepted (here the one-time test run's form: the chosen candidate only);
    # a directory of someone else's is refused with status 2
    assert sel.main([str(root), "--suite", str(suite), "--out", str(out), "--quiet",
                     "--candidates", "fused-gated"]) == 0
    rerun = json.loads((out / "selection.json").read_text())
    assert set(rerun["table"]) == {"sweep", "fused", "fused-gated", *sel.CONTEXT_METHODS}
    other = tmp_path / "mine"
    other.mkdir()
    (other / "notes.txt").write_text("keep")
    capsys.readouterr()
    assert sel.main([str(root), "--suite", str(suite), "--out", str(other), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "notes.txt" in err[0] and (other / "notes.txt").read_text() == "keep"
