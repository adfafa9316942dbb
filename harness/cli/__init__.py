"""The ``tri360`` command line: argument parsing only, one thin module per command.

Each command module exposes ``HELP``, ``add_arguments(parser)`` and ``run(args) -> int`` and calls the module of
:mod:`harness.commands` named after the command (:data:`COMMANDS`: command name -> its module here).
Anticipated failures (bad input, unknown name, malformed file, an unusable output path) print one line naming the
culprit and exit with status 2; Ctrl-C exits with status 130 and one line at any
moment, the seconds of start-up included (the imports below run under a SIGINT handler that exits at once; only
Python's own start-up before this module runs, tens of milliseconds, is the interpreter's).
Nothing half-written is left behind (every writer is atomic).
"""

from __future__ import annotations

from harness.runtime import startup

startup.guard("tri360")
# every import below runs under the guard (so ruff's E402 is off for this file, in pyproject.toml)
import argparse
import os
import sys

from harness import __version__
from harness.cli import evaluate, export, import_, list_methods, perturb, reconstruct, render, report, score, study
from harness.cli import scenes as scenes_cmd
from harness.data.errors import UserError
from harness.runtime.arguments import EXIT_USAGE
from harness.runtime.arguments import ArgumentParser as OneLineParser
from scenes.registry import SceneError

EXIT_BROKEN_PIPE = 141
"""Exit status when the reader of stdout went away (``tri360 methods | head``): 128 + SIGPIPE, as a shell pipeline's
commands that die of SIGPIPE have; nothing is printed."""

COMMANDS = {"render": render, "scenes": scenes_cmd, "methods": list_methods, "reconstruct": reconstruct,
            "evaluate": evaluate,
            "score": score, "report": report, "study": study, "perturb": perturb, "import": import_,
            "export": export}


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Shows ``(default: X)`` where a default says something; options whose default is None (meaning "see
    the text"), False (plain switches) or an empty list (repeatable options) get none."""

    def _get_help_string(self, action):
        if action.default is None or action.default is False or action.default == []:
            return action.help
        return super()._get_help_string(action)


class ArgumentParser(OneLineParser):
    """An argument error is one line, ``tri360 CMD: error: ...`` and where to look, and exit status 2
    (:class:`harness.runtime.arguments.ArgumentParser`).  Subcommand parsers are made of the same class
    (``add_subparsers``)."""

    def parse_args(self, args=None, namespace=None):
        """As argparse's, but unrecognized arguments are reported by the command's parser (``tri360 CMD``)."""
        ns, extra = self.parse_known_args(args, namespace)
        if extra:
            getattr(ns, "_parser", self).error(f"unrecognized arguments: {' '.join(extra)}")
        return ns


def build_parser() -> argparse.ArgumentParser:
    parser = ArgumentParser(prog="tri360", description=__doc__.splitlines()[0].strip("`. "))
    parser.add_argument("--version", action="version", version=f"tri360 {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, mod in COMMANDS.items():
        p = sub.add_parser(name, help=mod.HELP, description=mod.HELP,
                           formatter_class=HelpFormatter)
        mod.add_arguments(p)
        p.set_defaults(_module=mod, _parser=p)
    return parser


def _os_error_line(exc: OSError) -> str:
    where = exc.filename if exc.filename is not None else ""
    if exc.filename2 is not None:
        where = f"{where} -> {exc.filename2}"
    reason = exc.strerror or str(exc)
    return f"{where}: {reason}" if where else reason


def main(argv: list[str] | None = None) -> int:
    """Parse ``argv`` (default: the command line), run the command; its exit status.  Ctrl-C at any moment
    (parsing included) is one line and 130; SIGTERM while it runs is handled the same way (partial outputs
    removed), exit status 143.  With ``argv`` None (this process's own command line: the ``tri360`` script,
    ``python -m harness.cli``) Ctrl-C is ignored once the command has returned, during the interpreter's shutdown
    (:func:`harness.runtime.startup.finished`)."""
    prog = "tri360"
    try:
        with startup.sigterm_as_interrupt():
            args = build_parser().parse_args(argv)
            prog = f"tri360 {args.command}"
            status = int(args._module.run(args) or 0)
            sys.stdout.flush()  # a reader that went away shows here, not at the interpreter's exit
            return status
    except (UserError, SceneError) as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except BrokenPipeError:
        # stdout's reader has gone: the rest of the output and the final flush go nowhere, quietly
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_BROKEN_PIPE
    except OSError as exc:
        print(f"{prog}: error: {_os_error_line(exc)}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt as exc:
        print(startup.interrupted_line(prog, exc), file=sys.stderr)
        return startup.exit_status(exc)
    finally:
        if argv is None:
            startup.finished()


startup.release()  # from here on Ctrl-C is a KeyboardInterrupt, handled by main()


if __name__ == "__main__":
    sys.exit(main())
