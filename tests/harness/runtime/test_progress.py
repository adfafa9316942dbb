"""Progress: a tqdm bar on a terminal; elsewhere one plain line per finished item, never a carriage return."""

from __future__ import annotations

import io

from tqdm import tqdm

from harness.runtime.progress import LineProgress, progress_bar, track


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_without_a_terminal_each_finished_item_is_one_line():
    out = io.StringIO()
    with progress_bar(3, desc="render", unit="view", stream=out) as bar:
        assert isinstance(bar, LineProgress)
        for name in ("C", "U", "R"):
            bar.set_postfix_str(f"vp000/{name}")
            bar.update(1)
    text = out.getvalue()
    assert "\r" not in text and "\x1b" not in text
    lines = text.splitlines()
    assert len(lines) == 3
    assert lines[0].startswith("render: 1/3 views, ") and lines[0].endswith(" s (vp000/C)")
    assert lines[2].startswith("render: 3/3 views, ") and lines[2].endswith(" s (vp000/R)")


def test_disabled_prints_nothing_and_unknown_totals_count_up():
    out = io.StringIO()
    with progress_bar(5, desc="x", enabled=False, stream=out) as bar:
        bar.update(5)
    assert out.getvalue() == ""
    with progress_bar(None, desc="fused", unit="stage", stream=out) as bar:
        bar.update(1)
        bar.update(1)
    assert [line.split(",")[0] for line in out.getvalue().splitlines()] == ["fused: 1 stage", "fused: 2 stages"]


def test_on_a_terminal_it_is_a_tqdm_bar():
    out = Terminal()
    with progress_bar(2, desc="evaluate", unit="frame", stream=out) as bar:
        assert isinstance(bar, tqdm)
        bar.update(2)
    assert "\r" in out.getvalue() and "evaluate" in out.getvalue()


def test_min_interval_thins_the_lines_but_keeps_the_last(monkeypatch):
    out = io.StringIO()
    clock = iter(float(t) for t in range(100))
    monkeypatch.setattr("harness.runtime.progress.time.monotonic", lambda: next(clock))
    bar = progress_bar(10, desc="scipy", unit="pixel", min_interval_s=4, stream=out)
    for _ in range(10):
        bar.update(1)  # one clock second per item
    assert [line.split(",")[0] for line in out.getvalue().splitlines()] == [
        "scipy: 1/10 pixels", "scipy: 5/10 pixels", "scipy: 9/10 pixels", "scipy: 10/10 pixels"]


def test_track_yields_every_item_and_counts_after_each(capsys):
    seen = []
    for item in track(["a", "b"], desc="t", unit="item"):
        seen.append((item, capsys.readouterr().err))  # the line of an item comes once it is done
    assert [s for s, _ in seen] == ["a", "b"] and seen[0][1] == "" and seen[1][1].startswith("t: 1/2 items, ")
    assert capsys.readouterr().err.startswith("t: 2/2 items, ")
