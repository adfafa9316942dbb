"""The ``Method`` interface: whatever turns a frame into camera C's per-pixel distance.

Built-in methods (every configuration of the paper's flow pipeline, :mod:`reconstruction.methods.flow_pipeline`)
and outside ones (entry-point group ``tri360.methods``) implement the same protocol and are scored the same
way.  A method's ``label`` is stable and human-readable (``dis-rect:gradient``, ``deepflow-plain:average``),
and ``config()`` returns its full configuration, which ``config.json`` records beside every results set.

A method's ``run`` receives a :class:`MethodInput`, never the frame: the three images (read-only copies), the told
rig (poses, baseline) and the size, which is what a real rig would hand it.  No ground truth, no path, no provenance
(scene recipe, rig placement, a captured twin's true poses), no photometric record; built anew for every group of
methods, so nothing a method does to its input reaches the scorer or another method.

Two optional protocols extend :class:`Method`, each found with ``isinstance`` (a method that implements neither,
such as an outside method with only ``label``, ``config()`` and ``run()``, is unaffected):

* :class:`GroupedMethod`: methods that share work (the variants of one flow configuration share the flow and the
  triangulation) say so with a common ``group_key``; :func:`method_groups` puts them in one group and
  :func:`run_methods` runs each group once through the first member's ``run_group``.  Every other method is a group
  of its own and runs through its ``run``.
* :class:`ReferencingMethod`: a method that names the method whose distance the ground-truth-free quality measures
  compare its own with (``reference_method``; :func:`with_references`, :func:`reference_distance`).

The flow pipeline's group adds a third for the methods built on a flow-pipeline method's distance
(:class:`reconstruction.methods.flow_pipeline.BuiltOnFlow`).
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Protocol, runtime_checkable

import numpy as np

from reconstruction.camera.rig import CAMERA_NAMES, CameraPose

__all__ = ["Method", "GroupedMethod", "ReferencingMethod", "MethodInput", "MethodOutput", "method_groups",
           "run_methods", "flow_fields", "with_references", "reference_distance"]


def _frozen(a) -> np.ndarray:
    """A read-only copy of ``a``."""
    out = np.array(a, copy=True)
    out.setflags(write=False)
    return out


@dataclass(frozen=True, eq=False)
class MethodInput:
    """What a method's ``run`` receives for one frame: what a real rig hands it, and nothing else.

    Built with copies of what it is given (:meth:`of` a frame), every array read-only and every mapping immutable,
    so a method can change neither the frame that is scored nor another method's input.

    Attributes:
        width, height: image size, pixels (``width == 2 * height``).
        baseline_m: the told baseline, metres.
        cameras: the told pose of each camera (``"C"``, ``"U"``, ``"R"``): :class:`CameraPose` with read-only
            ``position`` (3,) metres and ``rotation`` (3, 3) world-from-camera.
        images: (H, W, 3) uint8 sRGB image of each camera, RGB channel order, read-only.
    """

    width: int
    height: int
    baseline_m: float
    cameras: Mapping[str, CameraPose]
    images: Mapping[str, np.ndarray]

    def __post_init__(self) -> None:
        cameras = {name: CameraPose(_frozen(np.asarray(self.cameras[name].position, np.float64)),
                                    _frozen(np.asarray(self.cameras[name].rotation, np.float64)))
                   for name in CAMERA_NAMES}
        images = {name: _frozen(self.images[name]) for name in CAMERA_NAMES}
        object.__setattr__(self, "width", int(self.width))
        object.__setattr__(self, "height", int(self.height))
        object.__setattr__(self, "baseline_m", float(self.baseline_m))
        object.__setattr__(self, "cameras", MappingProxyType(cameras))
        object.__setattr__(self, "images", MappingProxyType(images))

    @classmethod
    def of(cls, frame) -> MethodInput:
        """The input of a method for ``frame`` (anything with ``width``, ``height``, ``baseline_m``, ``cameras``
        and ``images``: a :class:`harness.data.frame.Frame`, or another input): copies, nothing else of it."""
        return cls(frame.width, frame.height, frame.baseline_m, frame.cameras, frame.images)

    def __reduce__(self):
        # mapping proxies do not pickle: an input travels (to a Dask worker, to a method's own process) as plain
        # dicts and is frozen again on arrival
        return (MethodInput, (self.width, self.height, self.baseline_m, dict(self.cameras), dict(self.images)))


@dataclass
class MethodOutput:
    """What a method hands back for one frame.

    Attributes:
        distance: (H, W) float32 distance of camera C, metres; NaN, inf or <= 0 = no prediction.
        confidence: (H, W) float32, higher = more trustworthy, or None.
        seconds: wall time per stage, seconds (``total`` at least).
        info: free-form, JSON-able details (e.g. LM iterations).
        reference: (H, W) float32 an independent distance of camera C that the method computed on the way
            (metres; e.g. ``fused``'s flow-pipeline distance), or None.  The ground-truth-free quality measures
            use it (:func:`reconstruction.quality.disagreement`); it is not scored.
    """

    distance: np.ndarray
    confidence: np.ndarray | None = None
    seconds: dict[str, float] = field(default_factory=dict)
    info: dict[str, Any] = field(default_factory=dict)
    reference: np.ndarray | None = None

    @property
    def total_seconds(self) -> float:
        return float(self.seconds.get("total", sum(self.seconds.values())))


@runtime_checkable
class Method(Protocol):
    """A reconstruction method.

    Attributes:
        label: stable, human-readable name; the results' ``method`` column.
    """

    label: str

    def config(self) -> dict:
        """The full configuration (every parameter, JSON-able)."""
        ...

    def run(self, frame: MethodInput) -> MethodOutput:
        """Camera C's distance for the frame whose :class:`MethodInput` is ``frame``."""
        ...


@runtime_checkable
class GroupedMethod(Method, Protocol):
    """A method that shares work with others (e.g. :class:`reconstruction.methods.flow_pipeline.FlowMethod`: the
    variants of one flow configuration compute its flow once).

    :func:`method_groups` puts methods with equal, non-None ``group_key`` in one group, and :func:`run_methods` runs
    each group through its first member's ``run_group``, once per frame.
    """

    @property
    def group_key(self) -> Hashable | None:
        """Equal keys: the methods share work and run together; None: the method is a group of its own."""
        ...

    def run_group(self, frame: MethodInput, members: Sequence[Method],
                  on_stage: Callable[[str], None] | None = None) -> dict[str, MethodOutput]:
        """Run ``members`` (methods of this ``group_key``, this one among them) on one frame, sharing their work;
        ``on_stage`` is called with a stage name before each stage (progress display).

        Returns:
            Outputs by member label: each the output the member's own ``run`` gives.
        """
        ...


@runtime_checkable
class ReferencingMethod(Method, Protocol):
    """A method that names the method whose distance is its reference for the ground-truth-free quality measures
    (:func:`reconstruction.quality.assess`'s ``reference``; e.g. the default ``fused-mirror``'s refined flow)."""

    @property
    def reference_method(self) -> Method | None:
        """The reference method (run beside this one: :func:`with_references`), or None: no reference."""
        ...


def flow_fields(method) -> dict[str, Any]:
    """The results columns ``flow``, ``rectify`` and ``variant`` of a method (empty for methods that are not
    the flow pipeline)."""
    return {"flow": getattr(method, "flow_name", ""), "rectify": getattr(method, "rectify", ""),
            "variant": getattr(method, "variant", "")}


def method_groups(methods: Sequence[Method]) -> list[list[Method]]:
    """``methods`` split into the groups that share work (:class:`GroupedMethod` with the same ``group_key``), in
    order of first appearance; any other method (or one whose ``group_key`` is None) is a group of its own.
    :func:`run_methods` runs each group once; a distributed evaluation makes one task per frame and group."""
    groups: dict[Hashable, list] = {}
    for i, m in enumerate(methods):
        key = m.group_key if isinstance(m, GroupedMethod) else None
        groups.setdefault(("group", key) if key is not None else ("single", i), []).append(m)
    return list(groups.values())


def run_methods(frame, methods: Sequence[Method],
                on_stage: Callable[[str], None] | None = None) -> dict[str, MethodOutput]:
    """Run every method on one frame, each group of methods that share work once (:func:`method_groups`: through
    the first member's ``run_group`` when it is a :class:`GroupedMethod`, else through each member's ``run``).

    Args:
        frame: the frame.
        methods: methods with distinct labels.
        on_stage: called with a stage name before each stage (progress display).
    Returns:
        Outputs by method label, in the order of ``methods``.
    """
    outs: dict[str, MethodOutput] = {}
    for members in method_groups(methods):
        head = members[0]
        if isinstance(head, GroupedMethod):
            outs.update(head.run_group(frame, members, on_stage=on_stage))
        else:
            for m in members:
                if on_stage is not None:
                    on_stage(m.label)
                outs[m.label] = m.run(frame)
    return {m.label: outs[m.label] for m in methods}


def with_references(methods: Sequence[Method]) -> list[Method]:
    """``methods`` followed by the methods whose distance they name as their quality reference
    (:class:`ReferencingMethod`) and that are not among them (by label): run together (:func:`run_methods`), a reference
    of the same flow configuration shares the flow, and :func:`reference_distance` finds it in the outputs."""
    out = list(methods)
    labels = {m.label for m in out}
    for m in methods:
        ref = m.reference_method if isinstance(m, ReferencingMethod) else None
        if ref is not None and ref.label not in labels:
            out.append(ref)
            labels.add(ref.label)
    return out


def reference_distance(frame, method: Method, outputs: dict[str, MethodOutput]) -> np.ndarray | None:
    """The distance the quality measures compare ``method``'s with on ``frame`` (:func:`reconstruction.quality.
    assess`'s ``reference``).

    The method's own ``reference`` when its output has one; else, for a method that names one
    (:class:`ReferencingMethod`, e.g. the default ``fused-mirror``'s refined flow, which it does not compute itself),
    that method's distance: taken from ``outputs`` when the same run computed it, else run now.  None for a method
    without a reference.

    Args:
        frame: the frame; method: a method with an output in ``outputs``; outputs: outputs by label
            (:func:`run_methods`).
    Returns:
        (H, W) float32 metres, or None.
    """
    own = outputs[method.label].reference
    if own is not None:
        return own
    ref = method.reference_method if isinstance(method, ReferencingMethod) else None
    if ref is None:
        return None
    out = outputs.get(ref.label)
    if out is None:
        out = run_methods(frame, [ref])[ref.label]
    return np.asarray(out.distance, np.float32)
