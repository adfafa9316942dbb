"""Running methods blind: each is handed its :class:`reconstruction.methods.base.MethodInput`, never the frame.

Every command that runs methods (``evaluate``, ``score``, ``reconstruct``, a study, on a Dask worker or in this
process) runs them through :func:`run_blind`:

- **Built-in methods** (every object of the method, its flow backend and its refinement variant is tri360's own code:
  :func:`is_builtin`) run in this process, each group of methods that share work on a new :class:`MethodInput` of
  the frame: read-only copies of the images and of the told rig, and nothing else.
- **Outside methods** (a plugin's, or any object whose code is not tri360's) run in a process of their own that never
  holds the frame (:func:`harness.runtime.isolation.run_isolated`), one for each group of them on each frame.
- Two methods are handed the frame itself, and say so: the built-in flow pipeline with flow ``oracle`` (exact
  correspondences from C's true distance, :func:`needs_ground_truth`), and a predictions root being scored
  (:class:`harness.data.predictions.PredictionMethod`, which reads the frame's maps by its scene and viewpoint names).

The outputs of every group are gathered by method label, in the order of the methods.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Sequence

from harness.data.predictions import PredictionMethod
from harness.runtime.isolation import run_isolated
from reconstruction.flow.backends import ORACLE
from reconstruction.methods.base import Method, MethodInput, MethodOutput, method_groups, run_methods
from reconstruction.methods.flow_pipeline import FlowMethod

__all__ = ["needs_ground_truth", "is_builtin", "run_blind"]

#: the top-level packages whose code runs in this process: tri360's reconstruction and harness, and the objects
#: Python and numpy make (a method's parameters)
TRUSTED_PACKAGES = frozenset({"reconstruction", "harness", "builtins", "numpy"})
#: how deep :func:`is_builtin` follows a method's fields (a flow pipeline holds a backend, which holds a function)
_MAX_DEPTH = 6


def needs_ground_truth(method: Method) -> bool:
    """True for the one kind of method that is handed ground truth: the built-in flow pipeline with flow ``oracle``
    (exact correspondences from C's true distance, labelled ``oracle-...``).  A subclass or any outside method is
    never handed it, whatever it calls its flow."""
    return type(method) is FlowMethod and method.flow == ORACLE


def _hands_frame(method: Method) -> bool:
    """The methods that run on the frame itself (the module doc)."""
    return needs_ground_truth(method) or type(method) is PredictionMethod


def _code_packages(obj, depth: int = 0, seen: set[int] | None = None):
    """The top-level packages of the code ``obj`` carries: its type's, a function's own, and those of its fields
    (dataclass fields, items of lists, tuples and dicts, a partial's function), ``depth`` levels down."""
    seen = set() if seen is None else seen
    if id(obj) in seen or depth > _MAX_DEPTH:
        return
    seen.add(id(obj))
    yield type(obj).__module__.partition(".")[0]
    if isinstance(obj, functools.partial):
        yield from _code_packages(obj.func, depth + 1, seen)
    elif callable(obj) and not isinstance(obj, type) and hasattr(obj, "__module__"):
        yield str(obj.__module__).partition(".")[0]
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        for f in dataclasses.fields(obj):
            yield from _code_packages(getattr(obj, f.name, None), depth + 1, seen)
    elif isinstance(obj, list | tuple | frozenset | set):
        for item in obj:
            yield from _code_packages(item, depth + 1, seen)
    elif isinstance(obj, dict):
        for item in obj.values():
            yield from _code_packages(item, depth + 1, seen)


def is_builtin(method: Method) -> bool:
    """True if all the code ``method`` carries is tri360's own (:data:`TRUSTED_PACKAGES`): its class, and for a
    dataclass method its fields (a flow pipeline's backend and its functions, a refinement variant).  A plugin's
    method, a built-in method with a plugin's flow backend or variant, or a subclass defined elsewhere is not."""
    return all(p in TRUSTED_PACKAGES for p in _code_packages(method))


def run_blind(frame, methods: Sequence[Method],
              on_stage: Callable[[str], None] | None = None) -> dict[str, MethodOutput]:
    """Run ``methods`` on ``frame`` without handing them the frame (the module doc).

    Args:
        frame: the frame (:class:`harness.data.frame.Frame`), ground truth included.
        methods: methods with distinct labels.
        on_stage: called with a stage name before each stage (progress display).
    Returns:
        Outputs by method label, in the order of ``methods``.
    Raises:
        UserError: an outside method that cannot be sent to its process, or whose process ended without an answer
            (named); whatever a method raises is raised here.
    """
    framed = [m for m in methods if _hands_frame(m)]
    builtin = [m for m in methods if not _hands_frame(m) and is_builtin(m)]
    outside = [m for m in methods if not _hands_frame(m) and not is_builtin(m)]
    outs: dict[str, MethodOutput] = {}
    for group in method_groups(builtin):
        outs.update(run_methods(MethodInput.of(frame), group, on_stage=on_stage))
    for group in method_groups(outside):
        outs.update(run_isolated(MethodInput.of(frame), group, on_stage=on_stage))
    if framed:
        outs.update(run_methods(frame, framed, on_stage=on_stage))
    return {m.label: outs[m.label] for m in methods}
