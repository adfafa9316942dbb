"""A process of its own for an outside method: it never holds the frame, only the method's input.

:func:`run_isolated` starts a new Python process for a group of methods (``python -c``, so its command line names no
path), sends it ``sys.path``, the methods and their :class:`reconstruction.methods.base.MethodInput` on its standard
input (cloudpickle, so a method defined in a script travels too), and reads their outputs back from its standard
output (what the methods print goes to standard error).  Its call stack holds nothing of the caller's.  It costs
Python's start-up, the methods' own imports and the copy of the images, once per frame and group of methods.

This module imports nothing heavy: it is what that process imports first.
"""

from __future__ import annotations

import io
import os
import pickle
import signal
import subprocess
import sys
import traceback
from collections.abc import Callable, Sequence

import cloudpickle

from harness.data.errors import UserError
from reconstruction.methods.base import Method, MethodInput, MethodOutput, run_methods

__all__ = ["run_isolated", "child_main"]

#: what the process runs
_CHILD = "from harness.runtime.isolation import child_main; child_main()"


def run_isolated(inp: MethodInput, methods: Sequence[Method],
                 on_stage: Callable[[str], None] | None = None) -> dict[str, MethodOutput]:
    """Run ``methods`` (:func:`run_methods`) on ``inp`` in a new Python process that holds nothing else.

    The process runs in a session of its own (a terminal's Ctrl-C does not reach it) and is ended if this one is
    interrupted (Ctrl-C, SIGTERM) while it runs.

    Returns:
        Outputs by method label.
    Raises:
        UserError: a method that cannot be pickled, or a process that ended without an answer (named).
        Whatever a method raised, re-raised here (with the method's traceback as a note).
    """
    labels = ", ".join(m.label for m in methods)
    try:
        payload = pickle.dumps(list(sys.path)) + cloudpickle.dumps((list(methods), inp))
    except Exception as exc:
        raise UserError(f"method {labels}: cannot be sent to a process of its own ({type(exc).__name__}: {exc}); "
                        "an outside method must be picklable (cloudpickle)") from None
    if on_stage is not None:
        on_stage(labels)
    # a session of its own: a terminal's Ctrl-C reaches this process only, which ends the child (below) and says so
    # in one line; the child never prints a traceback of its own start-up
    proc = subprocess.Popen([sys.executable, "-c", _CHILD], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            start_new_session=True)
    try:
        answer, _ = proc.communicate(payload)
    except BaseException:
        proc.kill()
        proc.wait()
        raise
    try:
        status, value, trace = pickle.loads(answer)
    except Exception:
        raise UserError(f"method {labels}: its process ended without an answer (exit status {proc.returncode})"
                        ) from None
    if status != "ok":
        if trace:
            value.add_note(f"in the method's process:\n{trace}")
        raise value
    return value


def child_main() -> None:
    """The process of an outside method (:func:`run_isolated`): read ``sys.path``, the methods and their input on
    standard input, run them, write ``(status, outputs or exception, traceback text)`` on standard output."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)  # a SIGINT sent to it ends it without a word; the caller reports
    answer = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)  # what the method prints goes to standard error, never into the answer
    stream = io.BytesIO(sys.stdin.buffer.read())
    sys.path[:] = pickle.load(stream)
    try:
        methods, inp = cloudpickle.load(stream)
        message = ("ok", run_methods(inp, methods), "")
    except BaseException as exc:  # KeyboardInterrupt raised by a method included: raised again in the caller
        message = ("error", exc, traceback.format_exc())
    try:
        blob = cloudpickle.dumps(message)
    except Exception:  # an exception or output that does not pickle: its text
        blob = cloudpickle.dumps(("error", RuntimeError(f"{type(message[1]).__name__}: {message[1]}"), message[2]))
    answer.write(blob)
    answer.close()
