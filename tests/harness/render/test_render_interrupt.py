"""The Cycles worker process seen from outside: Ctrl-C, stdout hygiene, worker crashes and failures.

Every test here starts Blender (in the worker process), so all are marked ``blender``.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import harness.cli
import harness.render.cycles_renderer
from harness.cli import main
from harness.data.errors import UserError
from harness.render.base import RenderError, RenderSettings
from harness.render.registry import open_renderer
from harness.runtime.context import QUIET
from reconstruction.camera.rig import Rig
from scenes.model import Box, Material, ModelFile, SceneSpec
from tests.helpers import render_scene, sigint_default

pytestmark = pytest.mark.blender

_MAIN = "import sys; from harness.cli import main; sys.exit(main())"
CLI = ([sys.executable, "-m", "harness.cli"] if (Path(harness.cli.__file__).parent / "__main__.py").exists()
       else [sys.executable, "-c", _MAIN])
"""The real command line, in a fresh interpreter."""


def _children(pid: int) -> list[int]:
    try:
        return [int(p) for p in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]
    except FileNotFoundError:
        return []


def _cycles_workers(pid: int) -> list[int]:
    """``pid``'s children that run the Cycles worker (not another short-lived child, such as one a library's import
    starts while the command is still starting)."""
    found = []
    for child in _children(pid):
        with contextlib.suppress(FileNotFoundError, ProcessLookupError):
            if b"harness.render.cycles_worker" in Path(f"/proc/{child}/cmdline").read_bytes():
                found.append(child)
    return found


def _alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0] != "Z"
    except (FileNotFoundError, ProcessLookupError):
        return False


def _workdirs(tmp: Path) -> set[str]:
    return {p.name for p in tmp.glob("tri360-cycles-*")}


@contextlib.contextmanager
def _command(args: list[str], **kwargs):
    """The CLI in a new session (its own process group), text pipes, SIGINT at its default action (this test
    run may have it ignored); killed with its group if still running."""
    proc = subprocess.Popen([*CLI, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, preexec_fn=sigint_default, **kwargs)
    try:
        yield proc
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def _interrupt(proc: subprocess.Popen, group: bool, timeout: float) -> tuple[str, str, float]:
    """Ctrl-C: SIGINT to the process, or to its whole group as a terminal does; (stdout, stderr, seconds to exit)."""
    start = time.monotonic()
    if group:
        os.killpg(proc.pid, signal.SIGINT)
    else:
        proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=timeout)
    return stdout, stderr, time.monotonic() - start


@pytest.mark.parametrize("target", ["process", "group"])
def test_ctrl_c_stops_a_cycles_render_within_seconds(tmp_path, target):
    """SIGINT to the CLI (``process``), or to its whole process group as a terminal's Ctrl-C does (``group``):
    exit 130 within seconds, one line on stderr, the worker gone, nothing left in the output root."""
    out = tmp_path / "data"
    tmp = tmp_path / "tmp"  # the command's own temporary directory: other processes' renders do not show here
    tmp.mkdir()
    # classroom 400 x 200 at 128 samples renders for minutes on 2 cores (and for long enough on many); we interrupt
    # it after ~3 s, so the sample count costs nothing here
    with _command(["render", "--scene", "classroom", "--width", "400", "--samples", "128", "--out", str(out),
                   "--quiet"], env={**os.environ, "TMPDIR": str(tmp)}) as proc:
        deadline = time.monotonic() + 60
        while not _cycles_workers(proc.pid) and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        (worker,) = _cycles_workers(proc.pid)
        time.sleep(3.0)  # the worker builds the scene (~1 s) and is rendering camera C
        assert proc.poll() is None, "the render finished before it could be interrupted"
        stdout, stderr, seconds = _interrupt(proc, target == "group", timeout=30)
    assert proc.returncode == 130, (proc.returncode, stderr)
    assert seconds < 10, f"Ctrl-C took {seconds:.1f} s"
    assert stdout == ""
    lines = stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("tri360 render: interrupted"), stderr
    assert not _alive(worker), "the Cycles worker outlived the command"
    assert not out.exists() or not any(out.rglob("*")), f"left behind: {sorted(out.rglob('*'))}"
    assert not _workdirs(tmp), "the worker's temporary directory was left behind"


@pytest.mark.parametrize("flags", [["--quiet"], [], ["--verbose"]], ids=["quiet", "progress", "verbose"])
def test_stdout_of_a_cycles_render_holds_only_the_frame_dirs(tmp_path, flags):
    """Blender's and its libraries' chatter (e.g. "CUEW initialization failed") never reaches stdout."""
    out = tmp_path / "data"
    res = subprocess.run([*CLI, "render", "--scene", "box_room", "--width", "64", "--samples", "1",
                          "--viewpoints", "2", "--out", str(out), *flags], capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 0, res.stderr
    assert res.stdout.splitlines() == [str(out / "box_room" / "vp000"), str(out / "box_room" / "vp001")]
    if "--verbose" in flags:
        assert "Blender" in res.stderr or "Cycles" in res.stderr or "cycles" in res.stderr, "log not shown"
    if "--quiet" in flags:
        assert res.stderr == ""


def _room() -> SceneSpec:
    spec = SceneSpec(name="room", bounds=((-2, -2, 0), (2, 2, 3)))
    spec.add_material(Material("walls", kind="noise", contrast=0.5))
    spec.boxes.append(Box((0, 0, 1.5), (4, 4, 3), "walls", inward=True))
    return spec


def test_a_crashed_worker_is_one_line_naming_its_log(tmp_path, monkeypatch, capsys):
    real = harness.render.cycles_renderer.CyclesRenderer.render_camera
    logs = []

    def crash(self, name, pose):
        logs.append(self.log_path)
        os.kill(self._proc.pid, signal.SIGKILL)
        return real(self, name, pose)

    monkeypatch.setattr(harness.render.cycles_renderer.CyclesRenderer, "render_camera", crash)
    out = tmp_path / "data"
    assert main(["render", "--scene", "box_room", "--width", "64", "--samples", "1", "--out", str(out),
                 "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert ("tri360 render: error: the Cycles worker process was killed by SIGKILL while rendering camera C; "
            f"its log: {logs[0]}") == err
    assert logs[0].is_file() and not any(p for p in logs[0].parent.iterdir() if p != logs[0])
    assert not out.exists() or not any(out.rglob("*"))
    logs[0].unlink()
    logs[0].parent.rmdir()


def test_a_failing_scene_build_is_reported_with_the_reason(tmp_path):
    bad = tmp_path / "broken.blend"
    bad.write_bytes(b"not a blend file")
    spec = _room()
    spec.models.append(ModelFile(path=bad))
    with pytest.raises(RenderError, match="Cycles failed while building scene 'room' in Blender: .*; its log: ") as e:
        open_renderer("cycles", spec, RenderSettings(width=64, samples=1, threads=2, denoise=False))
    assert isinstance(e.value, UserError) and len(str(e.value).splitlines()) == 1
    log = Path(str(e.value).rsplit("its log: ", 1)[1])
    assert "Traceback" in log.read_text()
    log.unlink()
    log.parent.rmdir()


def test_worker_survives_sigint_and_renders_several_viewpoints(tmp_path):
    """One worker per scene: built once, it renders every viewpoint; a stray SIGINT does not stop it."""
    with open_renderer("cycles", _room(), RenderSettings(width=64, samples=1, threads=2, denoise=False)) as r:
        pid = r._proc.pid
        a = r.render(Rig(position=np.array([0.0, 0.0, 1.5])), "room", "vp000")
        os.kill(pid, signal.SIGINT)
        time.sleep(0.5)
        b = r.render(Rig(position=np.array([0.5, 0.0, 1.5])), "room", "vp001")
        assert r._proc.pid == pid
    assert not _alive(pid), "close() ends the worker"
    assert abs(a.distance["C"][16, 48] - 2.0) < 0.01 and abs(b.distance["C"][16, 48] - 1.5) < 0.01  # +X wall


def test_render_frames_runs_the_renderer_in_a_worker_not_here(tmp_path):
    render_scene("box_room", out_root=tmp_path, width=64, samples=1, threads=2, ctx=QUIET)
    assert "bpy" not in sys.modules


def _descendants(pid: int) -> list[int]:
    """Every process below ``pid``, whichever of their threads started them."""
    out, todo = [], [pid]
    while todo:
        parent, kids = todo.pop(), []
        for task in Path(f"/proc/{parent}/task").glob("*"):
            try:
                kids += [int(k) for k in (task / "children").read_text().split()]
            except (FileNotFoundError, ProcessLookupError):  # the thread or process just ended
                pass
        out += kids
        todo += kids
    return out


def _cmdline(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_text().replace("\0", " ")
    except (FileNotFoundError, ProcessLookupError):
        return ""


@pytest.mark.cluster
def test_ctrl_c_stops_a_study_on_a_local_cluster(tmp_path):
    """A study whose grid points render at once on a ``--workers 2`` LocalCluster: Ctrl-C (to the process group)
    exits 130 within seconds, leaves no process (scheduler, workers, Cycles) and no frame behind."""
    study = tmp_path / "s.toml"
    # 4 points of one 200 x 100 classroom frame at 2048 samples: minutes per frame, two at a time (interrupted
    # after seconds, so the sample count costs nothing here)
    study.write_text('[render]\nscene = "classroom"\nwidth = 200\nviewpoints = 1\nsamples = 2048\n'
                     '[evaluate]\nmethod = ["dis-rect:average"]\n[grid]\nbaseline = [0.2, 0.3, 0.4, 0.5]\n')
    out = tmp_path / "out"
    with _command(["study", str(study), "--out", str(out), "--workers", "2", "--quiet"]) as proc:
        deadline = time.monotonic() + 90
        while proc.poll() is None and time.monotonic() < deadline and len(
                [p for p in _descendants(proc.pid) if _alive(p) and "cycles_worker" in _cmdline(p)]) < 2:
            time.sleep(0.2)
        time.sleep(2.0)  # both workers are rendering their point's camera C
        family = _descendants(proc.pid)
        assert proc.poll() is None and len(family) >= 4, "the study ended, or never started two renders"
        _, stderr, seconds = _interrupt(proc, group=True, timeout=60)
    assert proc.returncode == 130, (proc.returncode, stderr)
    assert seconds < 20, f"Ctrl-C took {seconds:.1f} s"
    assert stderr.strip().splitlines()[-1].startswith("tri360 study: interrupted"), stderr
    deadline = time.monotonic() + 30  # the study's processes end with it; orphans are reaped asynchronously
    while [p for p in family if _alive(p)] and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not [p for p in family if _alive(p)], "processes outlived the study"
    assert not list(out.rglob("frame.json")) and not (out / "study.csv").exists()
