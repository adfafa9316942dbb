"""``python -m tools.bench`` (``make bench``): every benchmark runs whatever the others did, every goal is in the
summary, the exit status is 1 when anything failed, and Ctrl-C stops it at once with 130.  The benchmarks are
replaced by tiny scripts that print goal lines (no timing, no Blender)."""

from __future__ import annotations

import io
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.helpers import sigint_default
from tools.bench import __main__ as runner

ROOT = Path(__file__).resolve().parents[2]


def script(code: str) -> list[str]:
    return [sys.executable, "-c", code]


FAKE = {
    "pipeline": script("print('timings'); print('  [PASS] a <= 1: 0.5'); print('  [FAIL] b <= 2: 3'); exit(1)"),
    "sweep": script("import sys; print('sweep: --x: no such method', file=sys.stderr); exit(2)"),
    "render": script("print('  [PASS] c >= 3: 4')"),
    "dask_speedup": script("raise RuntimeError('boom')"),
    "suite": script("print('  [PASS] d: 1'); exit(1)"),
    "flow": script("print('  [PASS] e: 2')"),
}


def test_goal_lines_are_read_as_report_goals_prints_them():
    assert runner.goal_of("  [PASS] each variant <= 3 x: 2.1 x\n") == (True, "each variant <= 3 x: 2.1 x")
    assert runner.goal_of("  [FAIL] peak <= 2 GB: 3 GB") == (False, "peak <= 2 GB: 3 GB")
    assert runner.goal_of("render 1: 60.2 s [ok]") is None


def test_every_benchmark_runs_and_every_goal_is_summarised(monkeypatch, capsys):
    monkeypatch.setattr(runner, "command", FAKE.__getitem__)
    assert runner.main([]) == 1
    out = capsys.readouterr().out
    assert [x for x in out.splitlines() if x.startswith("==> ")] == [f"==> python -m tools.bench.{n}"
                                                                      for n in runner.BENCHES]
    summary = out[out.index("bench summary: "):].splitlines()
    assert summary[0] == "bench summary: 5 goals of 6 benchmarks, 4 FAIL lines"
    rows = [x.split(None, 2) for x in summary[1:]]
    assert rows == [["pipeline", "PASS", "a <= 1: 0.5"], ["pipeline", "FAIL", "b <= 2: 3"],
                    ["sweep", "FAIL", "exit status 2: an error (its line is above)"],
                    ["render", "PASS", "c >= 3: 4"],
                    ["dask_speedup", "FAIL", "exit status 1, no goal line (see its output above)"],
                    ["suite", "PASS", "d: 1"], ["suite", "FAIL", "exit status 1"],
                    ["flow", "PASS", "e: 2"]]


def test_all_goals_met_is_status_0_and_names_run_in_the_order_given(monkeypatch, capsys):
    monkeypatch.setattr(runner, "command", FAKE.__getitem__)
    assert runner.main(["flow", "render"]) == 0
    out = capsys.readouterr().out
    assert out.index("tools.bench.flow") < out.index("tools.bench.render")
    assert "bench summary: 2 goals of 2 benchmarks, all met" in out
    with pytest.raises(SystemExit):
        runner.main(["nope"])


def test_output_passes_through_line_by_line(monkeypatch):
    monkeypatch.setattr(runner, "command", lambda name: script("print('one'); print('  [PASS] two: 2')"))
    out = io.StringIO()
    run = runner.run_bench("x", out=out)
    assert out.getvalue() == "one\n  [PASS] two: 2\n"
    assert (run.name, run.status, run.goals) == ("x", 0, [(True, "two: 2")])


def test_ctrl_c_stops_the_running_benchmark_and_the_rest_at_once_with_130():
    """SIGINT to the process group, as the terminal sends it: the benchmark stops, no other starts, one line from
    the runner (after the benchmark's own), exit status 130, within seconds."""
    # the line that says it started is printed inside the try: a SIGINT right after it is the benchmark's to handle
    slow = ("import sys, time\\ntry:\\n    print('  [PASS] started: 1', flush=True)\\n    time.sleep(120)\\n"
            "except KeyboardInterrupt:\\n    print('slow: interrupted', file=sys.stderr)\\n    sys.exit(130)\\n")
    code = ("import sys\n"
            "from harness.runtime import startup\n"
            "startup.guard('bench')\n"
            "from tools.bench import __main__ as runner\n"
            f"runner.command = lambda name: [sys.executable, '-c', \"{slow}\"]\n"
            "sys.exit(startup.run_main(runner.main, 'bench'))\n")
    # SIGINT back to its default action: started from a background job (CI) it is inherited as ignored
    proc = subprocess.Popen([sys.executable, "-c", code], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True, preexec_fn=sigint_default)
    try:
        assert proc.stdout.readline().startswith("==> python -m tools.bench.pipeline")
        assert proc.stdout.readline() == "  [PASS] started: 1\n"  # the first benchmark is running
        start = time.monotonic()
        os.killpg(proc.pid, signal.SIGINT)
        out, err = proc.communicate(timeout=60)
        elapsed = time.monotonic() - start
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 130, (proc.returncode, err)
    assert elapsed < 10.0  # seconds: promptly, not after the 120 s the benchmark would have taken
    assert err.splitlines() == ["slow: interrupted",
                                "bench: interrupted during tools.bench.pipeline; the benchmarks after it were not run"]
    assert "==> " not in out and "bench summary" not in out
