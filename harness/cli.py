"""The ``tri360`` command line.

Each sub-command lives in its own module exposing ``add_arguments(parser)`` and ``run(args) -> int``.
Anticipated failures (bad input, unknown scene, malformed frame) print one line naming the culprit and
exit with status 2; nothing half-written is left behind (every writer is atomic).
"""

from __future__ import annotations

import argparse
import importlib
import sys

from harness import __version__

# name -> (module, one-line help)
COMMANDS = {
    "render": ("harness.render", "render frames of a registered scene into a data root"),
    "scenes": ("harness.render_scenes", "list the registered scenes and their presets"),
    "reconstruct": ("harness.reconstruct", "reconstruct per-pixel distance for one frame"),
    "evaluate": ("harness.evaluate", "reconstruct and score every frame under a data root"),
    "report": ("reports.cli", "write tables, plots, point clouds and report.html from a results dir"),
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="tri360", description=__doc__.splitlines()[0].strip("`. "))
    parser.add_argument("--version", action="version", version=f"tri360 {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, (module, help_) in COMMANDS.items():
        p = sub.add_parser(name, help=help_, description=help_,
                           formatter_class=argparse.ArgumentDefaultsHelpFormatter)
        mod = importlib.import_module(module)
        mod.add_arguments(p)
        p.set_defaults(_module=mod)
    return parser


def main(argv: list[str] | None = None) -> int:
    from harness.errors import UserError
    from harness.frame import FrameError
    from scenes import SceneError

    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args._module.run(args) or 0)
    except (UserError, FrameError, SceneError) as exc:
        print(f"tri360 {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"tri360 {args.command}: interrupted (finished outputs are complete; partial ones were removed)",
              file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
