"""Ctrl-C at any moment of the command, its start-up included (the imports of numba, pandas, matplotlib and Dask
take seconds): exit status 130 and one line on stderr, never a traceback.

The command is started with SIGINT at its default action (this test run may have it ignored, as a job started in
the background has).  Python's own start-up before any tri360 code runs (the interpreter and ``site``, tens of
milliseconds) is Python's business, so each Ctrl-C is sent a chosen delay after the command began loading its
modules (numpy's extension mapped into the process), wherever that lands: in the imports, in argument parsing or
in the render itself.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.helpers import sigint_default

CLI = [sys.executable, "-m", "harness.cli"]


def _loading_modules(pid: int) -> bool:
    """True once numpy's compiled extension is mapped into ``pid``: the command's own imports have begun."""
    try:
        return "numpy" in Path(f"/proc/{pid}/maps").read_text()
    except (FileNotFoundError, ProcessLookupError):
        return False


def _interrupt_after_loading(cmd: list[str], delay_s: float, cwd: Path | None = None) -> tuple[int, str]:
    """Start ``cmd`` (in ``cwd``) in its own session (SIGINT at its default action), wait until it loads its
    modules, sleep ``delay_s`` and Ctrl-C its whole process group as a terminal does; its exit status and stderr."""
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=cwd,
                            preexec_fn=sigint_default, start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while not _loading_modules(proc.pid) and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.002)
        assert proc.poll() is None, proc.communicate()
        time.sleep(delay_s)
        os.killpg(proc.pid, signal.SIGINT)
        _, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    return proc.returncode, stderr


@pytest.mark.parametrize("delay_s", [0.0, 0.05, 0.2,
                                     *(pytest.param(d, marks=pytest.mark.slow) for d in (0.5, 1.5, 4.0))])
def test_ctrl_c_during_start_up_or_run_is_one_line_and_130(tmp_path, delay_s):
    # a render that would take minutes (numpy ray-caster, many large frames): it is interrupted long before
    args = ["render", "--scene", "synthetic_box", "--width", "2000", "--viewpoints", "500",
            "--out", str(tmp_path / "data"), "--quiet"]
    code, stderr = _interrupt_after_loading([*CLI, *args], delay_s)
    lines = stderr.splitlines()
    assert code == 130, (code, stderr)
    assert len(lines) == 1 and "Traceback" not in stderr, stderr
    assert lines[0].startswith(("tri360: interrupted", "tri360 render: interrupted")), stderr


@pytest.mark.parametrize("delay_s", [0.0, 0.05, 0.2])
def test_ctrl_c_while_a_python_m_job_starts_is_one_line_and_130(tmp_path, delay_s):
    """``python -m tools.research.validate_quality`` from the repository root: the tool's imports (pandas, scipy,
    numba, OpenCV: over a second) run under the same guard, installed by the tool itself as ``__main__``; the
    delays stay well inside them (the tool would stop at once on its missing data root, with status 2)."""
    cmd = [sys.executable, "-m", "tools.research.validate_quality", str(tmp_path / "absent"), "--method", "sweep",
           "--out", str(tmp_path / "out")]
    code, stderr = _interrupt_after_loading(cmd, delay_s, cwd=Path(__file__).resolve().parents[3])
    assert code == 130, (code, stderr)
    assert stderr.splitlines() == ["validate_quality: interrupted while starting (nothing was done)"], stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_sigterm_during_a_render_removes_its_partial_frame_and_exits_143(tmp_path):
    """``kill`` (SIGTERM) while a frame is being written: the hidden staging directory goes, the frames already
    finished stay, one line on stderr, exit status 143."""
    out = tmp_path / "data"
    cmd = [*CLI, "render", "--scene", "synthetic_box", "--width", "1600", "--viewpoints", "50", "--out", str(out),
           "--quiet"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        deadline = time.monotonic() + 300
        staging = []
        while proc.poll() is None and time.monotonic() < deadline:
            staging = list(out.rglob(".*partial*")) if out.exists() else []
            if staging:
                break
            time.sleep(0.005)
        assert staging and proc.poll() is None, proc.communicate()
        proc.send_signal(signal.SIGTERM)
        _, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 143, (proc.returncode, stderr)
    assert stderr.splitlines() == ["tri360 render: terminated (finished outputs are complete; partial ones were "
                                   "removed)"], stderr
    assert not [p for p in out.rglob("*") if "partial" in p.name], sorted(out.rglob("*"))


@pytest.mark.parametrize("guarded", [False, True])
def test_the_resource_trackers_leaked_semaphore_warning_is_silenced_after_guard(guarded):
    """An interrupted command leaves its worker pool's semaphores to multiprocessing's resource tracker, which unlinks
    them after the command has exited and used to warn on stderr, after the command's one line.  The child here
    leaks one semaphore the same way (it exits without unlinking it): the warning appears without ``guard`` and not
    with it."""
    code = ("from harness.runtime import startup\n"
            + ("startup.guard('x')\n" if guarded else "")
            + "import multiprocessing, os\n"
              "lock = multiprocessing.get_context('spawn').Lock()\n"
              "os._exit(0)\n")
    # stderr is read to its end: the tracker holds it open until it has finished its report
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                         cwd=Path(__file__).resolve().parents[3])
    assert out.returncode == 0
    assert ("leaked semaphore" in out.stderr) is not guarded, out.stderr
