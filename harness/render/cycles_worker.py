"""The Cycles worker process: ``python -m harness.render.cycles_worker`` (started by ``CyclesRenderer``).

Why a process of its own: Cycles swallows ``KeyboardInterrupt`` inside its render callback (so Ctrl-C would
not stop a render), bpy is global state, and Blender and its libraries print to the C-level stdout.  Here
the worker ignores SIGINT (the parent kills it instead), keeps its stdin/stdout as the message channel and
points file descriptors 1 and 2 at its stderr (the parent's log file), so no Blender chatter ever reaches
the user's stdout.

Protocol: pickled tuples over the pipes, one request, one reply.

- parent -> worker: ``("open", spec, settings, workdir)``, then ``("camera", name, pose)`` any number of
  times, then ``("close",)`` (or EOF).
- worker -> parent: ``("ready", engine_info)`` after building the scene, ``("camera", image, distance)``
  per camera, or ``("error", "<Type>: <message>")`` for a request that failed (the traceback goes to
  the log); the worker exits after an error.

The worker also exits by itself within a second if its parent dies (it polls its parent process id).
"""

from __future__ import annotations

import importlib
import os
import pickle
import signal
import sys
import threading
import time
import traceback
from pathlib import Path

PARENT_POLL_S = 0.5


def _watch_parent(parent: int) -> None:
    """Exit the process once the parent is gone (it would be re-parented, so getppid changes)."""
    while True:
        time.sleep(PARENT_POLL_S)
        if os.getppid() != parent:
            os._exit(3)


def _channel() -> tuple:
    """Keep stdin/stdout as the message pipes and send everything else written to fd 1 to fd 2 (the log)."""
    chan_in = os.fdopen(os.dup(0), "rb")
    chan_out = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)
    devnull = os.open(os.devnull, os.O_RDONLY)
    os.dup2(devnull, 0)
    os.close(devnull)
    sys.stdout = sys.stderr
    return chan_in, chan_out


def main() -> int:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the whole process group: the parent decides
    chan_in, chan_out = _channel()
    threading.Thread(target=_watch_parent, args=(os.getppid(),), daemon=True).start()

    def send(msg) -> None:
        pickle.dump(msg, chan_out, protocol=pickle.HIGHEST_PROTOCOL)
        chan_out.flush()

    renderer, workdir = None, None
    while True:
        try:
            msg = pickle.load(chan_in)
        except EOFError:
            return 0
        try:
            if msg[0] == "open":
                _, spec, settings, workdir = msg
                cycles = importlib.import_module("harness.render.cycles")  # bpy loads here, and only here
                renderer = cycles.SceneRenderer(spec, settings)
                send(("ready", renderer.engine_info()))
            elif msg[0] == "camera":
                _, name, pose = msg
                print(f"tri360 worker: rendering camera {name}", file=sys.stderr, flush=True)
                image, distance = renderer.render_camera(name, pose, Path(workdir))
                send(("camera", image, distance))
            elif msg[0] == "close":
                return 0
            else:
                raise ValueError(f"unknown request {msg[0]!r}")
        except BrokenPipeError:
            return 1
        except Exception as exc:
            traceback.print_exc(file=sys.stderr)
            sys.stderr.flush()
            send(("error", " ".join(f"{type(exc).__name__}: {exc}".split())))  # one line
            return 1


if __name__ == "__main__":
    sys.exit(main())
