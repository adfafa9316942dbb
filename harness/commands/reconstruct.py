"""The reconstruct command: camera C's per-pixel distance for one frame by one method, written as ``tri360-pred/1``.

Writes under ``out`` (each file atomically)::

    <out>/<scene>/<viewpoint>/distance.exr     camera C's distance, metres
    <out>/<scene>/<viewpoint>/confidence.exr   if the method gives a confidence
    <out>/<scene>/<viewpoint>/cloud.ply        camera C's points coloured by C's image (binary PLY)
    <out>/<scene>/<viewpoint>/quality.exr      ground-truth-free quality maps (reconstruction.quality.assess)
    <out>/<scene>/<viewpoint>/reconstruction.json   seconds, method details, quality, metrics when the frame has GT
    <out>/method.json                          the method's name and full configuration

so ``out`` can be handed to ``tri360 score`` like any outside method's predictions.  ``out`` must be absent, empty
or a predictions root tri360 wrote (nothing else in it), never the frame, inside it or a parent of it
(:func:`harness.data.outputs.check_output`), and it holds one method: writing another method (or the same label with
other parameters) into a root that holds one is refused, so ``method.json`` describes every frame in it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

from harness.commands.evaluate import checked_maps
from harness.data import jsonio
from harness.data.atomic import atomic_write_bytes, atomic_write_text
from harness.data.errors import UserError
from harness.data.exr import write_exr_channels
from harness.data.frame import read_frame
from harness.data.names import check_name
from harness.data.outputs import check_output, mark_output
from harness.data.predictions import (
    prediction_dir,
    read_method_info,
    write_method_info,
    write_prediction,
)
from harness.data.provenance import software
from harness.runtime.blind import run_blind
from harness.runtime.context import IN_PROCESS, RunContext
from harness.runtime.progress import progress_bar
from reconstruction.methods.base import Method, MethodInput, MethodOutput, reference_distance, with_references
from reconstruction.quality import assess
from reports.metrics import summary
from reports.pointcloud import ply_bytes, point_grid

__all__ = ["run_with_progress", "reconstruct_to", "check_one_method"]


def run_with_progress(frame, methods: Sequence[Method], desc: str, progress: bool = True,
                      on_stage: Callable[[str], None] | None = None) -> dict[str, MethodOutput]:
    """:func:`harness.runtime.blind.run_blind` (no method but the oracle sees ground truth) with a stage progress
    bar; a method's ValueError (e.g. the oracle without ground
    truth) becomes a :class:`UserError` naming the frame."""
    with progress_bar(None, desc=desc, unit="stage", enabled=progress, leave=False) as bar:
        def note(name):
            bar.set_postfix_str(name)
            bar.update(1)
            if on_stage is not None:
                on_stage(name)
        try:
            return run_blind(frame, methods, on_stage=note)
        except ValueError as exc:
            raise UserError(f"{frame.path or frame.scene + '/' + frame.viewpoint}: {exc}") from None


def _method_info(method: Method) -> dict:
    """The contents of ``method.json`` for ``method`` (strict JSON values, as read back)."""
    config = method.config()
    return jsonio.to_jsonable({"name": method.label, "description": config.get("description", ""),
                               "parameters": config})


def _has_predictions(root: Path) -> bool:
    return any(p.is_file() for p in Path(root).glob("*/*/distance.exr"))


def check_one_method(out: Path, method: Method) -> None:
    """Refuse to write ``method`` into predictions root ``out`` when it holds another method's predictions.

    Raises:
        UserError: ``out``'s method.json names another method, or the same label with other parameters, or ``out``
            holds predictions without a method.json (their method is unknown); a malformed method.json (named).
    """
    out = Path(out)
    info = read_method_info(out)
    if not info:
        if _has_predictions(out):
            raise UserError(f"{out}: predictions root holds predictions but no method.json, so their method is "
                            f"unknown; one method per predictions root: write {method.label} into another --out")
        return
    want = _method_info(method)
    held = info.get("name", "")
    if held != want["name"]:
        raise UserError(f"{out}: predictions root holds method {held!r} ({out / 'method.json'}); one method per "
                        f"predictions root: write {method.label} into another --out")
    have = info.get("parameters", {})
    if have != want["parameters"]:
        keys = sorted(k for k in set(have) | set(want["parameters"]) if have.get(k) != want["parameters"].get(k))
        raise UserError(f"{out}: predictions root holds method {held!r} with other parameters (differing: "
                        f"{', '.join(keys[:5])}; {out / 'method.json'}); one configuration per predictions root: "
                        "choose another --out")


def reconstruct_to(frame_dir: Path, out: Path, method: Method, ctx: RunContext = IN_PROCESS) -> dict:
    """Reconstruct one frame with ``method`` and write its prediction in ``tri360-pred/1`` under ``out``.

    The output location is checked before any computation (usable, writable, a predictions root of this method or
    absent or empty, not the frame or around it; names safe); nothing is written unless the method succeeds.
    ``method.json`` is written before the maps, so it describes every frame of the root even after an interrupt.
    It runs in this process; ``ctx`` says whether a stage progress bar shows.

    Returns:
        The ``reconstruction.json`` contents (frame, method, seconds, metrics if the frame has ground truth).
    Raises:
        UserError: a malformed frame, an unusable output directory, or the method failing on the frame.
    """
    frame = read_frame(frame_dir)
    check_name(frame.scene, f"{Path(frame_dir) / 'frame.json'} (scene)")
    check_name(frame.viewpoint, f"{Path(frame_dir) / 'frame.json'} (viewpoint)")
    check_name(method.label, "--method")
    check_output(out, "predictions", [frame_dir])
    check_one_method(out, method)
    desc = f"{frame.scene}/{frame.viewpoint} {method.label}"
    # the quality reference (if the method names one it does not compute) runs along, sharing the flow
    outputs = run_with_progress(frame, with_references([method]), desc, ctx.progress)
    output = outputs[method.label]
    checked_maps(frame, method, output)
    info = {"frame": str(Path(frame_dir).resolve()), "scene": frame.scene, "viewpoint": frame.viewpoint,
            "method": method.label, "config": method.config(), "seconds": output.seconds, "info": output.info,
            "software": software()}
    quality_maps, info["quality"] = assess(frame, output.distance, output.confidence,
                                           reference_distance(MethodInput.of(frame), method, outputs))
    if frame.has_ground_truth:
        info["metrics"] = summary(output.distance, frame.distance["C"], output.confidence)
    method_info = _method_info(method)
    write_method_info(out, method_info)
    write_prediction(out, frame.scene, frame.viewpoint, output.distance, output.confidence)
    write_exr_channels(prediction_dir(out, frame.scene, frame.viewpoint) / "quality.exr", quality_maps)
    c = frame.cameras["C"]
    cloud, info["cloud_points"] = ply_bytes(point_grid(output.distance, c.position, c.rotation), frame.images["C"],
                                            comment=f"tri360 {method.label} {frame.scene}/{frame.viewpoint} camera C")
    atomic_write_bytes(prediction_dir(out, frame.scene, frame.viewpoint) / "cloud.ply", cloud)
    atomic_write_text(prediction_dir(out, frame.scene, frame.viewpoint) / "reconstruction.json",
                      jsonio.dumps(info, indent=2))
    mark_output(out, "predictions")
    return info
