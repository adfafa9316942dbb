"""Every benchmark of ``make bench``, one after the other, then one table of all their goals.

    python -m tools.bench [NAME ...]        # make bench; NAME: any of pipeline sweep render dask_speedup suite flow

Runs ``python -m tools.bench.<name>`` for each benchmark of :data:`BENCHES` (or each ``NAME``, in the order
given), each in its own process and whatever the earlier ones' outcome.  Their output passes through as it comes;
the goal lines they print (``  [PASS] ...`` / ``  [FAIL] ...``, :func:`tools.common.report_goals`) are collected.
At the end it prints ``bench summary: ...`` and one line per goal (benchmark, PASS or FAIL, the goal with its
measured figure), plus one ``FAIL`` line for each benchmark that exited with another status than its goals
explain (a crash, status 2 for an anticipated error, whose own line is above, or goals missing from its output).
The exit status is 1 when any of those lines says ``FAIL``, else 0.  Ctrl-C (SIGINT to the terminal's process
group) stops the running benchmark and this runner at once: one line, exit status 130 (SIGTERM: 143).
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("bench")

import os
import re
import signal
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

from harness.runtime.arguments import ArgumentParser

__all__ = ["BENCHES", "BenchRun", "goal_of", "command", "run_bench", "summary_lines", "main"]

#: the benchmarks of ``make bench``, in the order they run
BENCHES = ("pipeline", "sweep", "render", "dask_speedup", "suite", "flow")
#: the repository root, where ``python -m tools.bench.<name>`` finds ``tools``
ROOT = Path(__file__).resolve().parents[2]
#: a goal line of :func:`tools.common.report_goals`
GOAL_LINE = re.compile(r"^\s*\[(PASS|FAIL)\] (.*)$")
#: after Ctrl-C here, how long the running benchmark may take to stop on the Ctrl-C it got from the terminal (it may
#: be stopping a Dask cluster) before it is sent SIGINT, and then how long before SIGKILL, seconds
SAME_CTRL_C_S, STOP_GRACE_S = 10.0, 10.0


@dataclass
class BenchRun:
    """One benchmark's run: its name, exit status (negative: killed by that signal) and ``(met, text)`` goals."""

    name: str
    status: int = 0
    goals: list[tuple[bool, str]] = field(default_factory=list)

    @property
    def interrupted(self) -> bool:
        """The benchmark stopped on Ctrl-C or SIGTERM (its own status 130 / 143, or killed by the signal)."""
        return self.status in (startup.EXIT_INTERRUPTED, startup.EXIT_TERMINATED, -signal.SIGINT, -signal.SIGTERM)


def goal_of(line: str) -> tuple[bool, str] | None:
    """``(met, text)`` of a goal line ``  [PASS] text`` / ``  [FAIL] text``, else None."""
    m = GOAL_LINE.match(line.rstrip("\n"))
    return (m[1] == "PASS", m[2]) if m else None


def _stop(proc: subprocess.Popen, terminated: bool) -> None:
    """Stop a benchmark after Ctrl-C (``terminated``: SIGTERM) here.  A Ctrl-C at the terminal reached it too, so it
    gets :data:`SAME_CTRL_C_S` to stop by itself; then it is sent SIGINT (SIGTERM at once when ``terminated``, which
    only this process got), and SIGKILL after :data:`STOP_GRACE_S`."""
    for sig, wait_s in ((None, 0.0 if terminated else SAME_CTRL_C_S),
                        (signal.SIGTERM if terminated else signal.SIGINT, STOP_GRACE_S), (signal.SIGKILL, None)):
        if proc.poll() is not None:
            return
        if sig is not None:
            proc.send_signal(sig)
        try:
            proc.wait(timeout=wait_s)
            return
        except subprocess.TimeoutExpired:
            continue


def command(name: str) -> list[str]:
    """The command line of benchmark ``name``: ``python -m tools.bench.<name>`` with this interpreter."""
    return [sys.executable, "-m", f"tools.bench.{name}"]


def run_bench(name: str, out=None) -> BenchRun:
    """Run benchmark ``name`` (:func:`command`) from the repository root: its stdout is copied to ``out`` (default:
    this process's) line by line as it comes, stderr (its progress and error lines) goes straight to this process's,
    and its goal lines are collected.  On Ctrl-C or SIGTERM here it is stopped (:func:`_stop`) and the
    ``KeyboardInterrupt`` is raised again."""
    out = sys.stdout if out is None else out
    proc = subprocess.Popen(command(name), cwd=ROOT, stdout=subprocess.PIPE, text=True, bufsize=1,
                            env={**os.environ, "PYTHONUNBUFFERED": "1"})
    run = BenchRun(name)
    try:
        for line in proc.stdout:
            out.write(line)
            out.flush()
            goal = goal_of(line)
            if goal is not None:
                run.goals.append(goal)
        run.status = proc.wait()
    except KeyboardInterrupt as exc:
        _stop(proc, isinstance(exc, startup.Terminated))
        raise
    finally:
        proc.stdout.close()
    return run


def _why(run: BenchRun) -> str | None:
    """Why a benchmark's exit status is not explained by its goals (None when it is)."""
    if run.status == 0 and all(met for met, _ in run.goals):
        return None if run.goals else "exit status 0 but no goal line"
    if run.status == 1 and run.goals and not all(met for met, _ in run.goals):
        return None
    if run.status < 0:
        return f"killed by signal {-run.status}"
    if run.status == 2:
        return "exit status 2: an error (its line is above)"
    return f"exit status {run.status}" + ("" if run.goals else ", no goal line (see its output above)")


def summary_lines(runs: list[BenchRun]) -> tuple[list[str], bool]:
    """The summary table of ``runs`` and whether everything passed: a heading, then per benchmark one line per goal
    ``  <name>  PASS|FAIL  <goal>`` and a ``FAIL`` line when its exit status is not explained by its goals."""
    width = max([len(r.name) for r in runs] + [5])
    rows, failed, n_goals = [], 0, 0
    for run in runs:
        for met, text in run.goals:
            n_goals += 1
            failed += not met
            rows.append(f"  {run.name:<{width}s}  {'PASS' if met else 'FAIL'}  {text}")
        why = _why(run)
        if why is not None:
            failed += 1
            rows.append(f"  {run.name:<{width}s}  FAIL  {why}")
    ok = failed == 0
    head = (f"bench summary: {n_goals} goals of {len(runs)} benchmarks, "
            + ("all met" if ok else f"{failed} FAIL line{'s' if failed > 1 else ''}"))
    return [head, *rows], ok


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(prog="python -m tools.bench", description=__doc__.split("\n\n")[0])
    ap.add_argument("names", nargs="*", metavar="NAME",
                    help=f"benchmarks to run, in this order (default: all of {', '.join(BENCHES)})")
    args = ap.parse_args(argv)
    unknown = [n for n in args.names if n not in BENCHES]
    if unknown:
        ap.error(f"unknown benchmark {unknown[0]!r}; choose from {', '.join(BENCHES)}")
    runs = []
    for name in args.names or BENCHES:
        print(f"==> python -m tools.bench.{name}", flush=True)
        try:
            run = run_bench(name)
        except KeyboardInterrupt as exc:
            print(f"bench: {'terminated' if isinstance(exc, startup.Terminated) else 'interrupted'} during "
                  f"tools.bench.{name}; the benchmarks after it were not run", file=sys.stderr)
            return startup.exit_status(exc)
        if run.interrupted:  # stopped by a signal sent to it alone
            print(f"bench: tools.bench.{name} was interrupted; the benchmarks after it were not run", file=sys.stderr)
            return startup.EXIT_INTERRUPTED
        runs.append(run)
        print(flush=True)
    lines, ok = summary_lines(runs)
    print("\n".join(lines), flush=True)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(startup.run_main(main, "bench"))
