"""What the tools share: the argument parser of every tool (an argument error is one line and exit status 2),
goal lines and exit statuses (every benchmark), the bench frame (``pipeline``, ``flow``, ``sweep``), and the options,
cluster and output of the selection scripts (``select_matching``, ``select_photometric``).
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing as mp
import sys
import tempfile
import time
from collections.abc import Callable, Iterable
from pathlib import Path

from harness.data import jsonio
from harness.data.atomic import atomic_write_text
from harness.data.errors import UserError
from harness.data.frame import Frame, find_frames, read_frame, write_frame
from harness.data.outputs import mark_output
from harness.render.raycast import render_frame
from harness.runtime.arguments import EXIT_USAGE, ArgumentParser
from harness.runtime.cluster import ClusterOptions
from harness.runtime.context import RunContext
from scenes.model import choose_viewpoints
from scenes.registry import get_scene

__all__ = ["EXIT_USAGE", "ArgumentParser", "SCENE", "cell", "read_json_file", "user_error", "goal_line", "goals_status",
           "report_goals", "synthetic_box_frame", "load_or_render_frame", "selection_parser", "add_where_options",
           "run_selection"]

# ------------------------------------------------------------------------------------------------------ goals


def goal_line(ok: bool, text: str) -> str:
    """One goal as a benchmark prints it: ``  [PASS] text`` or ``  [FAIL] text``."""
    return f"  [{'PASS' if ok else 'FAIL'}] {text}"


def goals_status(results: Iterable[bool]) -> int:
    """The exit status of a benchmark that checked goals: 0 when every goal was met, 1 otherwise (so that
    ``make bench`` fails on a missed goal)."""
    return 0 if all(results) else 1


def report_goals(goals, out=print) -> int:
    """Print each ``(met, text)`` goal as a ``[PASS]`` / ``[FAIL]`` line through ``out``; return the exit status
    (:func:`goals_status`)."""
    for ok, text in goals:
        out(goal_line(ok, text))
    return goals_status([ok for ok, _ in goals])


def cell(x: float) -> str:
    """A metre or ratio figure in a tool's Markdown table: three decimals, ``-`` when not finite."""
    return f"{x:.3f}" if math.isfinite(x) else "-"


def read_json_file(path: Path, what: str, missing: str) -> dict:
    """The JSON object in ``path``, a file of the kind ``what`` (e.g. ``"regression bounds file"``).

    Raises:
        FileNotFoundError: ``path`` is missing: ``<path>: <missing>``.
        ValueError: one line naming ``path``: a directory, not JSON, or not a JSON object.
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: {missing}") from None
    except IsADirectoryError:
        raise ValueError(f"{path}: is a directory, not a {what}") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{path}: not a {what} (not JSON: {exc})") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: not a {what} (not a JSON object)")
    return data


def user_error(prog: str, exc: Exception) -> int:
    """Print a tool's one line ``<prog>: error: <message>`` for an anticipated failure on stderr (as the commands and
    the argument parser say it); return exit status 2."""
    print(f"{prog}: error: {exc}", file=sys.stderr)
    return EXIT_USAGE


# ------------------------------------------------------------------------------------------------ bench frame

SCENE = "synthetic_box"
"""The scene of the bench frame: boxes only, ray-cast by numpy, exact ground truth."""


def synthetic_box_frame(width: int, viewpoint: str, **options) -> Frame:
    """The :data:`SCENE` frame of seed 0 at its first viewpoint, ray-cast ``width`` x ``width/2`` and named
    ``viewpoint`` (``options``: :func:`harness.render.raycast.render_frame`'s, e.g. ``supersample``)."""
    entry, preset = get_scene(SCENE)
    spec = entry.spec(preset, seed=0)
    rig = choose_viewpoints(spec, 1, 0)[0]
    return render_frame(spec, rig, width, SCENE, viewpoint, **options)


def _render_into(root: str, width: int) -> None:
    write_frame(synthetic_box_frame(width, f"bench-w{width}"), Path(root))


def load_or_render_frame(directory: Path | None, width: int):
    """A synthetic_box frame ``width`` x ``width/2`` with ground truth.

    ``directory`` may be a frame directory, or a cache root searched for a frame of that width; if none is
    found one is rendered into it (into a temporary directory when ``directory`` is None).  Rendering runs
    in a child process so that its memory does not raise this process's peak.

    Returns:
        ``(frame, description)``.
    """

    tmp = None
    if directory is None:
        tmp = tempfile.TemporaryDirectory(prefix="tri360-bench-")
        directory = Path(tmp.name)
    directory = Path(directory)
    try:
        if (directory / "frame.json").is_file():
            frame = read_frame(directory)
            if frame.width != width:
                raise SystemExit(f"error: {directory} holds a {frame.width}-wide frame, --width is {width}")
            return frame, f"reused {directory}"
        for d in find_frames(directory) if directory.is_dir() else []:
            frame = read_frame(d)
            if frame.width == width and frame.has_ground_truth:
                return frame, f"reused {d}"
        start = time.perf_counter()
        proc = mp.get_context("spawn").Process(target=_render_into, args=(str(directory), width))
        proc.start()
        proc.join()
        if proc.exitcode != 0:
            raise SystemExit(f"error: rendering the bench frame into {directory} failed (exit {proc.exitcode})")
        found = [d for d in find_frames(directory) if read_frame(d, load_distance=False).width == width]
        frame = read_frame(found[0])
        where = "a temporary directory" if tmp else str(found[0])
        return frame, f"rendered into {where} in {time.perf_counter() - start:.1f} s"
    finally:
        if tmp is not None:
            tmp.cleanup()


# ---------------------------------------------------------------------------------------- selection scripts


def selection_parser(module: str, description: str, default_suite: Path, suite_help: str,
                     candidates_help: str) -> argparse.ArgumentParser:
    """The options every selection script takes: ``DATA_ROOT``, ``--out``, ``--suite``, ``--split``, ``--quiet``,
    ``--candidates`` and where to run (``--workers N`` | ``--scheduler ADDRESS``); the script adds its own."""
    parser = ArgumentParser(prog=f"python -m {module}", description=description)
    parser.add_argument("data_root", type=Path, metavar="DATA_ROOT")
    parser.add_argument("--out", type=Path, required=True, help="results set to write (with selection.md/json)")
    parser.add_argument("--suite", type=Path, default=default_suite, help=suite_help)
    parser.add_argument("--split", choices=("dev", "test"), default="dev", help="suite split")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--candidates", nargs="+", default=None, metavar="LABEL", help=candidates_help)
    add_where_options(parser)
    return parser


def add_where_options(parser: argparse.ArgumentParser) -> None:
    """Where a script's evaluation runs: ``--workers N`` (a local Dask cluster) or ``--scheduler ADDRESS``, one of
    them (:func:`run_selection` reads them)."""
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, default=None, metavar="N",
                       help="one task per frame on a Dask LocalCluster of N single-threaded workers on 127.0.0.1")
    where.add_argument("--scheduler", default=None, metavar="ADDRESS", help="an existing Dask scheduler")


def run_selection(prog: str, args: argparse.Namespace,
                  select: Callable[[RunContext], tuple[str, dict]]) -> int:
    """Run a selection script's ``select(ctx)`` (``ctx``: where to run, from ``--workers``/``--scheduler``, and
    ``--quiet``) -> ``(selection.md's text,
    selection.json's contents)``, write both into ``args.out`` (the results set it evaluated into) and print the
    text; exit status 0, or 2 with one line ``<prog>: <message>`` on a :class:`UserError`."""
    try:
        cluster = ClusterOptions(scheduler=args.scheduler, workers=args.workers)
        if cluster.distributed:
            cluster.check()
        text, payload = select(RunContext(cluster if cluster.distributed else None, progress=not args.quiet))
        atomic_write_text(args.out / "selection.md", text)
        atomic_write_text(args.out / "selection.json", jsonio.dumps(payload))
        mark_output(args.out, "results")
    except UserError as exc:
        return user_error(prog, exc)
    print(text)
    return 0
