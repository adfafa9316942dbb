"""Shared test helpers: exact synthetic frames made by the numpy ray-caster (no Blender); children that a test
sends Ctrl-C; Dask clusters started outside tri360 (only for tests marked ``cluster``); the ground-truth
consistency check of a rendered frame across its cameras."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import fields
from pathlib import Path

import cv2
import numpy as np
from distributed import Client

from harness.commands.render import render_frames
from harness.render.base import RenderSettings
from harness.render.raycast import render_frame
from reconstruction.camera.equirect import bearing_grid, project
from scenes.model import choose_viewpoints
from scenes.registry import get_scene


def make_synthetic_frame(width: int = 160, viewpoint: int = 0, preset: str | None = None, seed: int = 0):
    """A synthetic_box frame with exact ground truth (width x width/2)."""
    entry, preset = get_scene("synthetic_box" + (f":{preset}" if preset else ""))
    spec = entry.spec(preset, seed=seed)
    rig = choose_viewpoints(spec, viewpoint + 1, seed)[viewpoint]
    return render_frame(spec, rig, width, "synthetic_box", f"vp{viewpoint:03d}")


def sigint_default() -> None:
    """``preexec_fn`` of a child process that a test sends SIGINT: SIGINT back to its default action.

    A process started from a background job (``cmd &``, CI runners, ``nohup``) inherits SIGINT as ignored, and
    Python then leaves it ignored (rightly: such a process is not meant to get the terminal's Ctrl-C), so
    without this a test's Ctrl-C would never arrive.
    """
    signal.signal(signal.SIGINT, signal.SIG_DFL)


ROOT = Path(__file__).resolve().parents[1]
DASK = str(Path(sys.executable).parent / "dask")
STARTUP_S = 90.0
"""Bound on a Dask scheduler's or worker's start-up (generous: the machine may be slow and busy)."""

CURRENT_TEST = {"nodeid": "", "cluster": False}
"""The running test and whether it is marked ``cluster`` (kept by ``tests/conftest.py``)."""


def require_cluster_marker(what: str) -> None:
    """Refuse to start a Dask cluster in a test not marked ``cluster`` (``make test-fast`` must start none)."""
    if not CURRENT_TEST["cluster"]:
        raise RuntimeError(f"{CURRENT_TEST['nodeid'] or 'this test'} starts {what} but is not marked "
                           "@pytest.mark.cluster")


def _dask_env() -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), *filter(None, [env.get("PYTHONPATH")])])
    return env


@contextlib.contextmanager
def external_cluster(tmp: Path, n_workers: int = 2, tls: dict | None = None):
    """``dask scheduler`` + ``n_workers`` x ``dask worker`` (1 thread each, with a nanny) on 127.0.0.1, random
    ports; yields ``(address, processes)``; every process is stopped at the end."""
    require_cluster_marker("a Dask scheduler and workers")
    tmp.mkdir(parents=True, exist_ok=True)
    sched_file = tmp / "scheduler.json"
    tls_args = []
    if tls:
        tls_args = ["--tls-ca-file", tls["ca"], "--tls-cert", tls["cert"], "--tls-key", tls["key"]]
    procs: list[subprocess.Popen] = []
    logs = []

    def start(args, name):
        log = open(tmp / f"{name}.log", "wb")  # noqa: SIM115 (closed below)
        logs.append(log)
        procs.append(subprocess.Popen([DASK, *args], cwd=tmp, env=_dask_env(), stdout=log,
                                      stderr=subprocess.STDOUT, start_new_session=True))

    try:
        # --dashboard-address: even with --no-dashboard, scheduler and workers serve HTTP (health, metrics),
        # by default on 0.0.0.0; docs/scale-out.md gives the same commands
        start(["scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
               "--dashboard-address", "127.0.0.1:0", "--scheduler-file",
               str(sched_file), *(["--protocol", "tls"] if tls else []), *tls_args], "scheduler")
        deadline = time.monotonic() + STARTUP_S
        while not sched_file.is_file():
            assert procs[0].poll() is None, (tmp / "scheduler.log").read_text()
            assert time.monotonic() < deadline, "scheduler did not start"
            time.sleep(0.2)
        address = json.loads(sched_file.read_text())["address"]
        for i in range(n_workers):
            start(["worker", address, "--nthreads", "1", "--host", "127.0.0.1", "--no-dashboard",
                   "--dashboard-address", "127.0.0.1:0",
                   "--name", f"w{i}", *tls_args], f"worker{i}")
        yield address, procs
    finally:
        for p in reversed(procs):
            with contextlib.suppress(ProcessLookupError):
                os.killpg(p.pid, signal.SIGTERM)
        for p in reversed(procs):
            try:
                p.wait(timeout=15)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(p.pid, signal.SIGKILL)
                p.wait(timeout=15)
        for log in logs:
            log.close()


def wait_for_workers(address: str, n: int, security=None) -> list[int]:
    """Wait until ``n`` workers are connected and answer (a worker killed by an earlier test may still be listed
    for a moment, and its nanny's replacement may still be starting); their process ids."""
    deadline = time.monotonic() + STARTUP_S
    with Client(address, security=security, timeout=STARTUP_S) as c:
        while True:
            c.wait_for_workers(n, timeout=max(1.0, deadline - time.monotonic()))
            try:
                pids = c.run(os.getpid, on_error="raise")
            except (OSError, TimeoutError) as exc:  # a worker that is going away
                error = exc
            else:
                if len(pids) >= n:
                    return sorted(pids.values())
                error = None
            assert time.monotonic() < deadline, f"{n} workers did not all answer: {error}"
            time.sleep(0.2)


SETTING_NAMES = frozenset(f.name for f in fields(RenderSettings))


def render_scene(scene: str, **kw):
    """``render_frames(RenderSettings(<the settings among kw>), scene, <the rest of kw>)``: lets a test vary a
    setting and a job argument the same way (``{**opts, **change}``)."""
    settings = RenderSettings(**{k: kw.pop(k) for k in list(kw) if k in SETTING_NAMES})
    return render_frames(settings, scene, **kw)


def sample_equirect(img: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Bilinear sample of an equirect image (H, W[, C]) at continuous pixel coordinates u, v (pixel centres at
    integers, as ``reconstruction.camera.equirect``), wrapping around in longitude."""
    big = np.concatenate([img[:, -1:], img, img[:, :1]], axis=1).astype(np.float32)
    return cv2.remap(big, (u + 1).astype(np.float32), v.astype(np.float32), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_REPLICATE)


def cross_camera_consistency(frame, k: str, rel_tol: float = 0.02):
    """Ground-truth consistency of camera ``k`` (U or R) with C: project C's ground-truth points into ``k``.

    Returns ``(agree, occluded, grey_diff)``, each (H, W) over C's pixels: ``agree`` where ``k``'s own distance
    at the projection matches the point's distance from ``k`` within ``rel_tol`` (relative); ``occluded`` where a
    nearer surface within a pixel hides the point from ``k`` (0.4 m parallax around furniture), so it cannot
    agree; ``grey_diff`` the |grey level difference| (0-255) between C's pixel and ``k`` at the projection.
    """
    W, H = frame.width, frame.height
    c, pk = frame.cameras["C"], frame.cameras[k]
    X = c.position + frame.distance["C"][..., None] * bearing_grid(W, H, c.rotation)
    u, v = project(X, pk.position, pk.rotation, W, H)
    expected = np.linalg.norm(X - pk.position, axis=-1)
    agree = np.abs(sample_equirect(frame.distance[k], u, v) - expected) < rel_tol * expected
    nearest3x3 = cv2.erode(frame.distance[k].astype(np.float32), np.ones((3, 3), np.uint8),
                           borderType=cv2.BORDER_REPLICATE)
    occluded = sample_equirect(nearest3x3, u, v) < (1.0 - rel_tol) * expected
    grey = {n: cv2.cvtColor(frame.images[n], cv2.COLOR_RGB2GRAY).astype(np.float32) for n in ("C", k)}
    return agree, occluded, np.abs(sample_equirect(grey[k], u, v) - grey["C"])
