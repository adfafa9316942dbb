"""The ``tri360`` command line: argument parsing only, one thin module per command.

Each command module exposes ``HELP``, ``add_arguments(parser)`` and ``run(args) -> int`` and calls into
``harness.jobs``.  Anticipated failures (bad input, unknown name, malformed file, an unusable output path)
print one line naming the culprit and exit with status 2; Ctrl-C exits with status 130.  Nothing
half-written is left behind (every writer is atomic).
"""

from __future__ import annotations

import argparse
import sys

from harness import __version__
from harness.cli import evaluate, import_, perturb, reconstruct, render, report, score, study
from harness.cli import scenes as scenes_cmd
from harness.data.errors import UserError
from scenes.registry import SceneError

COMMANDS = {"render": render, "scenes": scenes_cmd, "reconstruct": reconstruct, "evaluate": evaluate,
            "score": score, "report": report, "study": study, "perturb": perturb, "import": import_}
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Shows ``(default: X)`` where a default says something; options whose default is None (meaning "see
    the text"), False (plain switches) or an empty list (repeatable options) get none."""

    def _get_help_string(self, action):
        if action.default is None or action.default is False or action.default == []:
            return action.help
        return super()._get_help_string(action)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="tri360", description=__doc__.splitlines()[0].strip("`. "))
    parser.add_argument("--version", action="version", version=f"tri360 {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, mod in COMMANDS.items():
        p = sub.add_parser(name, help=mod.HELP, description=mod.HELP,
                           formatter_class=HelpFormatter)
        mod.add_arguments(p)
        p.set_defaults(_module=mod)
    return parser


def _os_error_line(exc: OSError) -> str:
    where = exc.filename if exc.filename is not None else ""
    if exc.filename2 is not None:
        where = f"{where} -> {exc.filename2}"
    reason = exc.strerror or str(exc)
    return f"{where}: {reason}" if where else reason


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args._module.run(args) or 0)
    except (UserError, SceneError) as exc:
        print(f"tri360 {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except OSError as exc:
        print(f"tri360 {args.command}: error: {_os_error_line(exc)}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print(f"tri360 {args.command}: interrupted (finished outputs are complete; partial ones were removed)",
              file=sys.stderr)
        return EXIT_INTERRUPTED


if __name__ == "__main__":
    sys.exit(main())
