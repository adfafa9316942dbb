"""Ctrl-C while a command starts: one line and exit status 130, never a library's traceback; SIGTERM after it
handled as Ctrl-C (partial outputs removed), exit status 143.

A command's imports (numba, pandas, matplotlib, Dask) take seconds; a ``KeyboardInterrupt`` raised inside one of
them would unwind through the library and print its traceback.  :func:`guard` replaces Python's SIGINT handler by
one that prints one line and exits 130 at once (nothing has been done yet); :func:`release` puts Python's handler
back when the imports are done, so that from then on Ctrl-C is a ``KeyboardInterrupt`` that the command handles
(removing partial outputs).  Only Python's own handler is replaced: SIGINT ignored (a command started in the
background) stays ignored, a program that set its own handler keeps it, and off the main thread nothing changes.
Python's own start-up before the guard is set, tens of milliseconds, is the interpreter's.

SIGTERM (``kill``, a batch system's time limit) would end the process at once and leave the hidden staging
directory of an output half-written.  While a command runs (:func:`sigterm_as_interrupt`, used by the CLI's
``main`` and :func:`run_main`), SIGTERM with its default action raises :class:`Terminated`, a
``KeyboardInterrupt``: the same context managers remove partial outputs, and the command says ``terminated`` and
exits 143 (128 + SIGTERM).  During the imports before, nothing has been written, and SIGTERM keeps its default
action.

Once the command has returned, :func:`finished` ignores Ctrl-C: what is left is the interpreter's shutdown (joining
threads, exit callbacks, freeing modules; about half a second with Dask loaded), and Python puts SIGINT back to its
default action part-way through it, so that a Ctrl-C there killed the process without a word although every output
was complete.  Ignored, the exit status stays the command's own.

When a command with local workers is interrupted, the process pool's semaphores are not unlinked by the command;
multiprocessing's resource tracker (a process of its own, sharing stderr) unlinks them after the command has exited
and warns about each "leaked semaphore" on stderr, after the command's one line.  :func:`guard` silences exactly that
warning in the processes multiprocessing starts (the tracker among them): it adds a ``-W`` option for it to
``sys.warnoptions``, which they inherit.

This module imports nothing heavy, so that it can be the first thing a command loads.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
from collections.abc import Callable, Iterator

__all__ = ["EXIT_INTERRUPTED", "EXIT_TERMINATED", "TRACKER_WARNINGS", "Terminated", "interrupted_line", "exit_status",
           "guard", "release", "sigterm_as_interrupt", "finished", "run_main"]

EXIT_INTERRUPTED = 130
EXIT_TERMINATED = 128 + signal.SIGTERM


class Terminated(KeyboardInterrupt):
    """Raised by the SIGTERM handler of :func:`sigterm_as_interrupt`: handled wherever Ctrl-C is, exit status
    143."""


_guard: dict[str, object] = {}  # the handler installed by guard() and the one it replaced
#: the warnings filter (``-W`` syntax) for multiprocessing's resource tracker's report of the semaphores it unlinks
TRACKER_WARNINGS = "ignore::UserWarning:multiprocessing.resource_tracker"


def interrupted_line(prog: str, exc: BaseException | None = None) -> str:
    """What a command says when Ctrl-C (or SIGTERM: ``exc`` a :class:`Terminated`) stops it after start-up (its
    context managers removed partial outputs)."""
    what = "terminated" if isinstance(exc, Terminated) else "interrupted"
    return f"{prog}: {what} (finished outputs are complete; partial ones were removed)"


def exit_status(exc: BaseException) -> int:
    """130 for Ctrl-C, 143 for SIGTERM (:class:`Terminated`)."""
    return EXIT_TERMINATED if isinstance(exc, Terminated) else EXIT_INTERRUPTED


def _terminated(signum, frame) -> None:
    signal.signal(signal.SIGTERM, signal.SIG_IGN)  # one clean-up; a second SIGTERM does not interrupt it
    raise Terminated()


def guard(prog: str) -> bool:
    """Catch Ctrl-C from now until :func:`release`: ``<prog>: interrupted while starting (nothing was done)`` and
    exit status 130.  False (and nothing changed) when SIGINT does not have Python's default handler or this is
    not the main thread.  In any case the processes multiprocessing starts from now on get :data:`TRACKER_WARNINGS`
    (module docstring)."""
    if TRACKER_WARNINGS not in sys.warnoptions:
        sys.warnoptions.append(TRACKER_WARNINGS)
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


@contextlib.contextmanager
def sigterm_as_interrupt() -> Iterator[None]:
    """While inside: SIGTERM raises :class:`Terminated` if it had its default action (main thread only); the
    previous action is put back on the way out."""
    installed = False
    if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
        try:
            signal.signal(signal.SIGTERM, _terminated)
            installed = True
        except ValueError:  # not the main thread
            pass
    try:
        yield
    finally:
        if installed:
            signal.signal(signal.SIGTERM, signal.SIG_DFL)


def finished() -> None:
    """The command has returned and the process is about to exit: ignore Ctrl-C from now on (main thread only;
    elsewhere nothing changes)."""
    with contextlib.suppress(ValueError):
        signal.signal(signal.SIGINT, signal.SIG_IGN)


def run_main(main: Callable[[], int | None], prog: str) -> int:
    """Run a ``python -m`` job's ``main()`` after :func:`release`; Ctrl-C during it is one line on stderr
    (``<prog>: interrupted``) and 130, SIGTERM ``terminated`` and 143 (the job's own context managers have removed
    partial outputs by then).  For a process's ``__main__`` only: on the way out it calls :func:`finished`."""
    release()
    try:
        with sigterm_as_interrupt():
            return int(main() or 0)
    except KeyboardInterrupt as exc:
        print(interrupted_line(prog, exc), file=sys.stderr)
        return exit_status(exc)
    finally:
        finished()
