"""Ctrl-C while a command starts: one line and exit status 130, never a library's traceback.

A command's imports (numba, pandas, matplotlib, Dask) take seconds; a ``KeyboardInterrupt`` raised inside one of
them would unwind through the library and print its traceback.  :func:`guard` replaces Python's SIGINT handler by
one that prints one line and exits 130 at once (nothing has been done yet); :func:`release` puts Python's handler
back when the imports are done, so that from then on Ctrl-C is a ``KeyboardInterrupt`` that the command handles
(removing partial outputs).  Only Python's own handler is replaced: SIGINT ignored (a command started in the
background) stays ignored, a program that set its own handler keeps it, and off the main thread nothing changes.
Python's own start-up before the guard is set, tens of milliseconds, is the interpreter's.

This module imports nothing heavy, so that it can be the first thing a command loads.
"""

from __future__ import annotations

import os
import signal
import sys
from collections.abc import Callable

__all__ = ["EXIT_INTERRUPTED", "interrupted_line", "guard", "release", "run_main"]

EXIT_INTERRUPTED = 130
_guard: dict[str, object] = {}  # the handler installed by guard() and the one it replaced


def interrupted_line(prog: str) -> str:
    """What a command says when Ctrl-C stops it after start-up (its context managers removed partial outputs)."""
    return f"{prog}: interrupted (finished outputs are complete; partial ones were removed)"


def guard(prog: str) -> bool:
    """Catch Ctrl-C from now until :func:`release`: ``<prog>: interrupted while starting (nothing was done)`` and
    exit status 130.  False (and nothing changed) when SIGINT does not have Python's default handler or this is
    not the main thread."""
    if signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        return False
    line = f"{prog}: interrupted while starting (nothing was done)\n".encode()

    def interrupted(signum, frame) -> None:
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # a second Ctrl-C does not print a second line
        os.write(2, line)
        os._exit(EXIT_INTERRUPTED)

    try:
        signal.signal(signal.SIGINT, interrupted)
    except ValueError:  # not the main thread
        return False
    _guard.update(handler=interrupted, previous=signal.default_int_handler)
    return True


def release() -> None:
    """Put Python's SIGINT handler back if :func:`guard`'s is still the one installed (else leave it)."""
    handler = _guard.pop("handler", None)
    previous = _guard.pop("previous", None)
    if handler is not None and signal.getsignal(signal.SIGINT) is handler:
        signal.signal(signal.SIGINT, previous)


def run_main(main: Callable[[], int | None], prog: str) -> int:
    """Run a ``python -m`` job's ``main()`` after :func:`release`; Ctrl-C during it is one line on stderr
    (``<prog>: interrupted``) and 130 (the job's own context managers have removed partial outputs by then)."""
    release()
    try:
        return int(main() or 0)
    except KeyboardInterrupt:
        print(interrupted_line(prog), file=sys.stderr)
        return EXIT_INTERRUPTED
