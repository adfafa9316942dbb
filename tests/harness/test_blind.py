"""What a method is handed (harness.runtime.blind, harness.runtime.isolation, reconstruction.methods.base.MethodInput):
read-only copies of the images and the told rig, nothing else; outside methods in a process of their own."""

from __future__ import annotations

import dataclasses
import functools
import os
import pickle

import numpy as np
import pytest

from harness.data.errors import UserError
from harness.runtime.blind import is_builtin, needs_ground_truth, run_blind
from harness.runtime.isolation import run_isolated
from reconstruction.flow.backends import get_flow
from reconstruction.methods.base import MethodInput, MethodOutput
from reconstruction.methods.flow_pipeline import FlowMethod
from reconstruction.methods.registry import builtin_methods, flow_methods
from tests.helpers import make_synthetic_frame


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


def test_an_outside_method_runs_in_another_process(frame):
    out = run_blind(frame, [Constant()])["constant"]
    assert out.info["pid"] != os.getpid()
    assert out.info["attributes"] == ["baseline_m", "cameras", "height", "images", "of", "width"]
    np.testing.assert_array_equal(out.distance, 2.0)  # a constant, exact


def test_a_builtin_method_runs_here(frame):
    dis = flow_methods(["dis"], [True], ["average"])[0]
    out = run_blind(frame, [dis])[dis.label]
    assert out.distance.shape == (frame.height, frame.width)


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


def test_a_method_whose_process_dies_is_named(frame):
    with pytest.raises(UserError, match=r"method dying: its process ended without an answer \(exit status 3\)"):
        run_isolated(MethodInput.of(frame), [Dying()])
