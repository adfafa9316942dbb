"""The ``cycles`` backend: Blender Cycles, run in a worker process built once per scene.

:class:`CyclesRenderer` starts ``python -m harness.render.cycles_worker`` (plain ``subprocess``, not
``multiprocessing``, so it also works inside daemonic worker processes such as Dask's), sends it the scene
once and then one request per camera, over pickled messages on the worker's stdin/stdout.  This process never
imports ``bpy``.  Why a worker (see :mod:`harness.render.cycles_worker`): Ctrl-C must stop a render within
seconds (Cycles itself swallows ``KeyboardInterrupt``), and Blender's own output must stay out of our stdout.

- The worker ignores SIGINT.  On ``KeyboardInterrupt`` or any other exception here, the worker is killed
  (SIGKILL) and reaped before the exception propagates; nothing of the frame was written yet, so nothing
  partial is left.
- The worker's stdout and stderr go to ``<workdir>/cycles.log`` in a temporary directory that is removed
  when the renderer closes cleanly or is interrupted; when the worker fails or crashes the log is kept and
  the :class:`RenderError` names it.  With ``verbose=True`` the worker's output goes to our stderr instead.
"""

from __future__ import annotations

import os
import pickle
import shutil
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

import harness
from harness.render.base import BaseRenderer, RenderError, scene_label
from reconstruction.camera.rig import CameraPose

WORKER_MODULE = "harness.render.cycles_worker"
KILL_WAIT_S = 5.0


class CyclesRenderer(BaseRenderer):
    """Blender Cycles (path tracing, OpenImageDenoise) in a worker process; draws everything a spec holds."""

    name = "cycles"
    description = "Blender Cycles path tracer (bpy, CPU) in a worker process; boxes, lights and model files"
    # every setting but ``threads`` and ``supersample``: Cycles gives bit-identical pixels and distance with 1 or 2
    # threads (checked on classroom:small, 128 px, 4 samples, OIDN on), and supersample is the ray-caster's
    pixel_settings = ("width", "samples", "seed", "denoise", "max_bounces", "diffuse_bounces", "glossy_bounces",
                      "filter_width", "clamp_indirect", "light_tree", "denoise_prefilter", "denoise_quality",
                      "adaptive_threshold", "adaptive_min_samples")

    _proc: subprocess.Popen | None = None
    _workdir: Path | None = None

    def _build(self) -> None:
        self._workdir = Path(tempfile.mkdtemp(prefix="tri360-cycles-"))
        self.log_path = self._workdir / "cycles.log"
        self._doing = f"starting Blender for scene {scene_label(self.spec)!r}"
        env = dict(os.environ)
        package_root = str(Path(harness.__file__).resolve().parents[1])  # so the worker imports this harness
        env["PYTHONPATH"] = os.pathsep.join([package_root, *filter(None, [env.get("PYTHONPATH")])])
        try:
            with open(self.log_path, "ab") as log:
                self._proc = subprocess.Popen([sys.executable, "-m", WORKER_MODULE], stdin=subprocess.PIPE,
                                              stdout=subprocess.PIPE, stderr=None if self.verbose else log,
                                              env=env, close_fds=True)
            self._doing = f"building scene {scene_label(self.spec)!r} in Blender"
            reply = self._request(("open", self.spec, self.settings, str(self._workdir)))
        except BaseException:
            self._abort()
            raise
        self._engine = reply[1]

    def engine(self) -> dict:
        return dict(self._engine)

    def render_camera(self, name: str, pose: CameraPose) -> tuple[np.ndarray, np.ndarray]:
        self._doing = f"rendering camera {name}"
        try:
            _, image, distance = self._request(("camera", name, pose))
        except BaseException:
            self._abort()
            raise
        return image, distance

    def _request(self, msg: tuple) -> tuple:
        """Send one request, wait for its reply; a worker failure becomes a one-line :class:`RenderError`."""
        if self._proc is None:
            raise RenderError("the Cycles renderer is closed")
        try:
            pickle.dump(msg, self._proc.stdin, protocol=pickle.HIGHEST_PROTOCOL)
            self._proc.stdin.flush()
            reply = pickle.load(self._proc.stdout)
        except (EOFError, BrokenPipeError, pickle.UnpicklingError, ConnectionResetError):
            raise RenderError(f"the Cycles worker process {self._exit_status()} while {self._doing}; "
                              f"{self._log_hint()}") from None
        if reply[0] == "error":
            raise RenderError(f"Cycles failed while {self._doing}: {reply[1]}; {self._log_hint()}")
        return reply

    def _exit_status(self) -> str:
        try:
            code = self._proc.wait(timeout=KILL_WAIT_S)
        except subprocess.TimeoutExpired:
            return "stopped answering"
        if code < 0:
            try:
                return f"was killed by {signal.Signals(-code).name}"
            except ValueError:
                return f"was killed by signal {-code}"
        return f"exited with status {code}"

    def _log_hint(self) -> str:
        if self.verbose:
            return "its output is above"
        self._keep_log = True
        return f"its log: {self.log_path}"

    def _abort(self) -> None:
        """Kill and reap the worker now (Ctrl-C, errors); keeps the log only if a failure named it."""
        proc, self._proc = self._proc, None
        if proc is not None:
            if proc.poll() is None:
                proc.kill()
            try:
                proc.wait(timeout=KILL_WAIT_S)
            except subprocess.TimeoutExpired:
                pass
            for pipe in (proc.stdin, proc.stdout):
                try:
                    pipe.close()
                except OSError:
                    pass
        self._cleanup()

    def _cleanup(self) -> None:
        workdir, self._workdir = self._workdir, None
        if workdir is None:
            return
        if getattr(self, "_keep_log", False):  # leave the log the error message named, drop the rest
            for p in workdir.iterdir():
                if p != self.log_path:
                    shutil.rmtree(p, ignore_errors=True) if p.is_dir() else p.unlink(missing_ok=True)
        else:
            shutil.rmtree(workdir, ignore_errors=True)

    def close(self) -> None:
        """Ask the worker to exit (killing it if it does not within a few seconds) and remove the workdir."""
        proc = self._proc
        if proc is not None and proc.poll() is None:
            try:
                pickle.dump(("close",), proc.stdin)
                proc.stdin.close()
                proc.wait(timeout=KILL_WAIT_S)
            except (OSError, subprocess.TimeoutExpired):
                pass
        self._abort()

    def __del__(self):
        if self._proc is not None:
            self._abort()
