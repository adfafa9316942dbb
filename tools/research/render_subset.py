"""Render the first viewpoints of every group of a suite split, with their twins: the subset the selection scripts
take with ``--partial``.

Run as::

    python -m tools.research.render_subset DATA_ROOT [--suite suites/tri360-v2.toml] [--split dev]
        [--viewpoints 1] [--conditions captured ...] [--twins-only] [--quiet]

Every group's rigs are placed as ``tri360 render --suite`` places them (the same scene, seed and rig: a frame
rendered here is the suite's frame, byte for byte in its settings), then only its first ``--viewpoints``
viewpoints are rendered (complete frames are kept) and the twins of the conditions asked for derived from them.
A full split takes hours on a 2-core machine; vp000 of every group is the subset the selections report.
"""

from __future__ import annotations

from harness.runtime import startup

if __name__ == "__main__":  # run as a script: Ctrl-C during the imports below is one line and 130
    startup.guard("render_subset")

import sys
from pathlib import Path

from harness.commands.parts.suite import derive_twins, load, plan, render_planned
from harness.data.errors import UserError
from harness.data.frame import frame_dir, is_complete
from harness.data.outputs import check_output, ensure_output_dir, mark_output
from harness.data.suite import IDEAL
from harness.runtime.context import RunContext
from tools.common import ArgumentParser, user_error

__all__ = ["render_subset", "main"]

PROG = "python -m tools.research.render_subset"


def render_subset(suite_path: Path, split: str, out_root: Path, viewpoints: int = 1,
                  conditions: tuple[str, ...] | None = None, progress: bool = True,
                  twins_only: bool = False) -> list[Path]:
    """Render the first ``viewpoints`` frames of every group of ``split`` into ``out_root`` and derive their twins
    of ``conditions`` (None: every condition of the suite); complete frames are kept.  ``twins_only``: render
    nothing, derive the twins of the frames already rendered.  Returns the dirs of the frames now complete."""
    if viewpoints < 1:
        raise UserError(f"--viewpoints must be >= 1, got {viewpoints}")
    suite = load(suite_path)
    known = (IDEAL, *suite.conditions)
    unknown = [c for c in (conditions or ()) if c not in known]
    if unknown:
        raise UserError(f"unknown condition(s) {', '.join(unknown)} (suite {suite.name}: {', '.join(known)})")
    wanted = set(conditions or known) | {IDEAL}
    planned = [p for p in plan(suite, split) if p.frame.index < viewpoints and p.frame.condition in wanted]
    out_root = check_output(Path(out_root), "data")
    for scene in dict.fromkeys(p.frame.scene for p in planned):
        ensure_output_dir(out_root / scene)
    ctx = RunContext(None, progress=progress)
    todo = [p for p in planned if not is_complete(frame_dir(out_root, p.frame.scene, p.frame.viewpoint))]
    rendered = [p for p in todo if p.frame.condition == IDEAL]
    if rendered and not twins_only:
        render_planned(suite, split, rendered, out_root, ctx)
    mark_output(out_root, "data")
    twins = [p for p in todo if p.frame.condition != IDEAL
             and is_complete(frame_dir(out_root, p.frame.source.scene, p.frame.viewpoint))]
    if twins:
        derive_twins(suite, split, twins, out_root, ctx)
    return [d for d in (frame_dir(out_root, p.frame.scene, p.frame.viewpoint) for p in planned) if is_complete(d)]


def main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(prog=PROG, description="render the first viewpoints of every group of a suite split")
    parser.add_argument("data_root", type=Path, metavar="DATA_ROOT")
    parser.add_argument("--suite", type=Path, default=Path("suites/tri360-v2.toml"))
    parser.add_argument("--split", choices=("dev", "test"), default="dev")
    parser.add_argument("--viewpoints", type=int, default=1, help="viewpoints per group (default: 1, vp000)")
    parser.add_argument("--conditions", nargs="+", default=None, metavar="NAME",
                        help="twins to derive (default: every condition of the suite)")
    parser.add_argument("--twins-only", action="store_true",
                        help="render nothing: derive the twins of the frames already rendered")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    try:
        dirs = render_subset(args.suite, args.split, args.data_root, args.viewpoints,
                             None if args.conditions is None else tuple(args.conditions), not args.quiet,
                             args.twins_only)
    except UserError as exc:
        return user_error(PROG, exc)
    print(f"{len(dirs)} frame(s) in {args.data_root}")
    return 0


if __name__ == "__main__":
    sys.exit(startup.run_main(main, "render_subset"))
