"""What a method is handed (harness.runtime.blind, harness.runtime.isolation, reconstruction.methods.base.MethodInput):
read-only copies of the images and the told rig, nothing else; outside methods in a process of their own."""

from __future__ import annotations

import dataclasses
import functools
import os
import pickle
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from harness.data.errors import UserError
from harness.data.frame import write_frame
from harness.runtime.blind import is_builtin, needs_ground_truth, run_blind
from harness.runtime.isolation import run_isolated
from reconstruction.flow.backends import get_flow
from reconstruction.methods.base import MethodInput, MethodOutput
from reconstruction.methods.flow_pipeline import FlowMethod
from reconstruction.methods.registry import builtin_methods, flow_methods
from tests.helpers import make_synthetic_frame, sigint_default


@pytest.fixture(scope="module")
def frame():
    return make_synthetic_frame(32)


class Constant:
    """An outside method: a constant distance, the process id it ran in, and what its input offers."""

    label = "constant"

    def config(self) -> dict:
        return {"kind": "constant"}

    def run(self, frame) -> MethodOutput:
        return MethodOutput(np.full((frame.height, frame.width), 2.0, np.float32),
                            info={"pid": os.getpid(), "attributes": sorted(a for a in dir(frame) if a[0] != "_")})


class Failing(Constant):
    label = "failing"

    def run(self, frame) -> MethodOutput:
        raise ValueError("this method always fails")


class Unpicklable(Constant):
    label = "unpicklable"

    def __reduce__(self):
        raise TypeError("not today")


class SubFlow(FlowMethod):
    """A subclass of the flow pipeline defined outside tri360."""


def test_an_input_holds_copies_and_nothing_else(frame):
    inp = MethodInput.of(frame)
    assert {f.name for f in dataclasses.fields(inp)} == {"width", "height", "baseline_m", "cameras", "images"}
    for k in "CUR":
        assert not np.shares_memory(inp.images[k], frame.images[k])
        np.testing.assert_array_equal(inp.images[k], frame.images[k])  # uint8 copies: equal exactly
        assert not inp.images[k].flags.writeable
        assert not inp.cameras[k].position.flags.writeable and not inp.cameras[k].rotation.flags.writeable
        assert not np.shares_memory(inp.cameras[k].position, frame.cameras[k].position)
    with pytest.raises(ValueError, match="read-only"):
        inp.images["C"][0, 0] = 0
    with pytest.raises(TypeError):
        inp.images["C"] = frame.images["U"]
    with pytest.raises(dataclasses.FrozenInstanceError):
        inp.width = 4


def test_an_input_survives_pickling_frozen(frame):
    inp = pickle.loads(pickle.dumps(MethodInput.of(frame)))
    assert (inp.width, inp.height) == (frame.width, frame.height)
    assert not inp.images["U"].flags.writeable
    np.testing.assert_array_equal(inp.images["U"], frame.images["U"])


def test_builtin_methods_are_builtin_and_outside_code_is_not():
    assert all(is_builtin(m) for m in builtin_methods())
    dis = flow_methods(["dis"], [True], ["average"])[0]
    assert not is_builtin(Constant())
    assert not is_builtin(SubFlow("dis"))
    # a built-in pipeline with an outside flow backend (here: a partial of an outside function) is outside code
    backend = dataclasses.replace(get_flow("dis"), compute=functools.partial(Constant.run, None))
    assert not is_builtin(dataclasses.replace(dis, flow=backend))
    assert is_builtin(dis)


def test_only_the_builtin_oracle_needs_ground_truth():
    oracle = flow_methods(["oracle"], [True], ["average"])[0]
    assert needs_ground_truth(oracle)
    assert not needs_ground_truth(SubFlow("oracle"))


@pytest.mark.slow
def test_an_outside_method_runs_in_another_process(frame):
    out = run_blind(frame, [Constant()])["constant"]
    assert out.info["pid"] != os.getpid()
    assert out.info["attributes"] == ["baseline_m", "cameras", "height", "images", "of", "width"]
    np.testing.assert_array_equal(out.distance, 2.0)  # a constant, exact


def test_a_builtin_method_runs_here(frame):
    dis = flow_methods(["dis"], [True], ["average"])[0]
    out = run_blind(frame, [dis])[dis.label]
    assert out.distance.shape == (frame.height, frame.width)


@pytest.mark.slow
def test_what_an_outside_method_raises_is_raised_here(frame):
    with pytest.raises(ValueError, match="always fails") as err:
        run_isolated(MethodInput.of(frame), [Failing()])
    assert any("in the method's process" in n for n in getattr(err.value, "__notes__", []))


def test_an_unpicklable_method_is_refused_in_one_line(frame):
    with pytest.raises(UserError, match="unpicklable: cannot be sent to a process of its own"):
        run_isolated(MethodInput.of(frame), [Unpicklable()])


class Dying(Constant):
    label = "dying"

    def run(self, frame) -> MethodOutput:
        os._exit(3)


@pytest.mark.slow
def test_a_method_whose_process_dies_is_named(frame):
    with pytest.raises(UserError, match=r"method dying: its process ended without an answer \(exit status 3\)"):
        run_isolated(MethodInput.of(frame), [Dying()])


SLOW_PLUGIN = '''
import os, time
from pathlib import Path
import numpy as np
from reconstruction.methods.base import MethodOutput


class Slow:
    label = "slow"

    def config(self):
        return {"kind": "slow"}

    def run(self, frame):
        Path(os.environ["SLOW_STARTED"]).write_text(str(os.getpid()))
        time.sleep(120)
        return MethodOutput(np.ones((frame.height, frame.width), np.float32))


METHODS = [Slow()]
'''


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return Path(f"/proc/{pid}/stat").read_text().split()[2] != "Z"


@pytest.mark.slow
def test_ctrl_c_while_an_outside_method_runs_is_one_line_and_ends_its_process(frame, tmp_path):
    """A plugin installed as a user would (an entry point on PYTHONPATH) runs in its own process; Ctrl-C to the
    command's process group while it runs: exit status 130, one line, and the method's process is gone."""
    site = tmp_path / "site"
    (site / "slowplug-0.1.dist-info").mkdir(parents=True)
    (site / "slowplug.py").write_text(SLOW_PLUGIN)
    (site / "slowplug-0.1.dist-info" / "METADATA").write_text("Metadata-Version: 2.1\nName: slowplug\nVersion: 0.1\n")
    (site / "slowplug-0.1.dist-info" / "entry_points.txt").write_text("[tri360.methods]\nslow = slowplug:METHODS\n")
    write_frame(frame, tmp_path / "data")
    started = tmp_path / "started"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")]),
           "SLOW_STARTED": str(started)}
    cmd = [sys.executable, "-m", "harness.cli", "evaluate", str(tmp_path / "data"), "--method", "slow", "--out",
           str(tmp_path / "res"), "--no-report"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                            preexec_fn=sigint_default, start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while not started.exists() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert started.exists(), proc.communicate()
        time.sleep(0.2)
        child = int(started.read_text())
        assert child != proc.pid
        os.killpg(proc.pid, signal.SIGINT)  # as a terminal's Ctrl-C: the command's whole process group
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 130, err
    assert len(err.strip().splitlines()) == 1, err
    deadline = time.monotonic() + 10
    while _alive(child) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not _alive(child)
    assert not (tmp_path / "res").exists()
