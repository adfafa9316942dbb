"""Benchmark of a suite's render cost: the median suite frame's render time over today's default classroom frame.

Run as ``python -m tools.bench.suite`` (part of ``make bench``).  Both are timed the same way, in this process, one
after the other: open the renderer on the scene (for Cycles: start the worker, build the scene), render the three
cameras, close it (nothing is written); the default render frame is ``tri360 render``'s default frame
(``classroom``, its default preset and seed, viewpoint ``vp000``, every render default), the suite frames are those
of ``--split`` (default ``dev``) with the suite's settings.  It prints each time, the goal as a ``[PASS]`` /
``[FAIL]`` line (exit status 1 when it is missed) and, last, ``suite render: ... = ratio R [ok: goal <= 1]`` (or
``[NOT MET: ...]``).

Goal: the median suite frame takes at most :data:`GOAL_RATIO` x the default frame.  What it protects: a suite's
render time is announced as its number of frames times the default frame's (docs/results-history.md), so a suite
frame must cost no more than the default one (measured 0.93 on an idle machine on 2026-12-02, 1.09 on 2026-12-03
when it was slower).  Both are timed on the same machine in the same run, so the goal is a ratio, which holds on
any machine; a load that changes during the run biases it, so run it on an otherwise idle machine.

By default one frame per family is timed (the first viewpoint of the family's first group in the split: 7 frames on
``tri360-v1`` dev), since the whole split takes about an hour; ``--all`` times every frame.  ``--width W`` renders
the default render frame and the suite frames at W instead (a quick check of the machinery, e.g. on a 2-frame
suite; the ratio is then not the goal's).  ``--threads`` as for ``tri360 render``.
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("bench_suite")

import dataclasses
import os
import statistics
import sys
import time
from pathlib import Path

from harness.commands.parts.suite import PlannedFrame, load, plan
from harness.commands.render import DEFAULT_SCENE, DEFAULTS
from harness.data.errors import UserError
from harness.render.registry import get_renderer
from scenes.model import choose_viewpoints
from scenes.registry import get_scene
from tools.common import ArgumentParser, report_goals, user_error

__all__ = ["GOAL_RATIO", "time_frame", "default_render_frame", "main"]

GOAL_RATIO = 1.0
DEFAULT_SUITE = Path("suites/tri360-v1.toml")


def time_frame(renderer: str, spec, settings, rig) -> float:
    """Wall seconds to open ``renderer`` on ``spec``, render ``rig``'s three cameras and close it."""
    t0 = time.perf_counter()
    with get_renderer(renderer)(spec, settings) as drawer:
        drawer.render(rig, scene="bench", viewpoint="vp000")
    return time.perf_counter() - t0


def default_render_frame(width: int | None = None, threads: int = 0):
    """``(renderer, spec, settings, rig)`` of ``tri360 render``'s default frame (optionally at another width)."""
    entry, preset = get_scene(DEFAULT_SCENE)
    spec = entry.build_spec(preset, DEFAULTS.seed)
    settings = dataclasses.replace(DEFAULTS, threads=threads, **({"width": width} if width else {}))
    rig = choose_viewpoints(spec, 1, DEFAULTS.seed)[0]
    return entry.renderer, spec, settings, rig


def _selected(planned: list[PlannedFrame], every: bool) -> list[PlannedFrame]:
    if every:
        return planned
    seen, out = set(), []
    for p in planned:
        if p.frame.entry.family not in seen:
            seen.add(p.frame.entry.family)
            out.append(p)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = ArgumentParser(prog="python -m tools.bench.suite", description=__doc__.splitlines()[0])
    ap.add_argument("--suite", type=Path, default=DEFAULT_SUITE, help="suite file")
    ap.add_argument("--split", default="dev", help="split whose frames are timed")
    ap.add_argument("--all", action="store_true", help="time every frame of the split (default: one per family)")
    ap.add_argument("--width", type=int, default=None, help="render everything at this width instead")
    ap.add_argument("--threads", type=int, default=0, help="CPU threads for Cycles (0 = all)")
    args = ap.parse_args(argv)
    try:
        suite = load(args.suite)
        planned = _selected(plan(suite, args.split, args.threads), args.all)
    except UserError as exc:
        return user_error("bench_suite", exc)
    width = args.width or int(suite.render["width"])
    print(f"suite render bench: {suite.name} ({suite.id}) split {args.split}, {len(planned)} frame(s) at "
          f"{width}x{width // 2}, {os.cpu_count()} cores", flush=True)
    default = default_render_frame(args.width, args.threads)
    t_default = time_frame(*default)
    print(f"  reference: default {DEFAULT_SCENE} frame at {default[2].width}x{default[2].height}: "
          f"{t_default:.1f} s "
          f"(load average before the next: {os.getloadavg()[0]:.1f})", flush=True)
    times = []
    for p in planned:
        settings = dataclasses.replace(p.settings, width=args.width) if args.width else p.settings
        t = time_frame(p.renderer, p.spec, settings, p.rig)
        times.append(t)
        print(f"  {p.frame.label} ({p.frame.entry.family}, {p.renderer}): {t:.1f} s", flush=True)
    median = statistics.median(times)
    ratio = median / t_default
    ok = ratio <= GOAL_RATIO
    status = report_goals([(ok, f"median suite frame at most {GOAL_RATIO:g} x the default {DEFAULT_SCENE} frame: "
                                f"{median:.1f} s / {t_default:.1f} s = {ratio:.2f} x")])
    print(f"suite render: median frame {median:.1f} s ({min(times):.1f}-{max(times):.1f} s over {len(times)} "
          f"frames) / default {DEFAULT_SCENE} frame {t_default:.1f} s = ratio {ratio:.2f} "
          f"[{'ok' if ok else 'NOT MET'}: goal <= {GOAL_RATIO:.0f}]", flush=True)
    return status


if __name__ == "__main__":
    sys.exit(startup.run_main(main, "bench_suite"))
