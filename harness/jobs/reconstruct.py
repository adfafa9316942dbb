"""The reconstruct job: camera C's per-pixel distance for one frame by one method, written as ``tri360-pred/1``.

Writes under ``out`` (each file atomically)::

    <out>/<scene>/<viewpoint>/distance.exr     camera C's distance, metres
    <out>/<scene>/<viewpoint>/confidence.exr   if the method gives a confidence
    <out>/<scene>/<viewpoint>/reconstruction.json   seconds, method details, metrics when the frame has GT
    <out>/method.json                          the method's name and full configuration

so ``out`` can be handed to ``tri360 score`` like any outside method's predictions.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

from harness.data import jsonio
from harness.data.atomic import atomic_write_text
from harness.data.errors import UserError
from harness.data.frame import read_frame
from harness.data.outputs import check_output_dir
from harness.data.predictions import prediction_dir, write_method_info, write_prediction
from harness.data.provenance import software
from harness.jobs.progress import progress_bar
from reconstruction.methods.base import Method, MethodOutput, run_methods
from reports.metrics import summary

__all__ = ["run_with_progress", "reconstruct_to"]


def run_with_progress(frame, methods: Sequence[Method], desc: str, progress: bool = True,
                      on_stage: Callable[[str], None] | None = None) -> dict[str, MethodOutput]:
    """:func:`run_methods` with a stage progress bar; a method's ValueError (e.g. the oracle without ground
    truth) becomes a :class:`UserError` naming the frame."""
    with progress_bar(None, desc=desc, unit="stage", enabled=progress, leave=False) as bar:
        def note(name):
            bar.set_postfix_str(name)
            bar.update(1)
            if on_stage is not None:
                on_stage(name)
        try:
            return run_methods(frame, methods, on_stage=note)
        except ValueError as exc:
            raise UserError(f"{frame.path or frame.scene + '/' + frame.viewpoint}: {exc}") from None


def reconstruct_to(frame_dir: Path, out: Path, method: Method, progress: bool = True) -> dict:
    """Reconstruct one frame with ``method`` and write its prediction in ``tri360-pred/1`` under ``out``.

    The output location is checked (usable, writable) before any computation; nothing is written unless the
    method succeeds.

    Returns:
        The ``reconstruction.json`` contents (frame, method, seconds, metrics if the frame has ground truth).
    Raises:
        UserError: a malformed frame, an unusable output directory, or the method failing on the frame.
    """
    frame = read_frame(frame_dir)
    check_output_dir(out)
    desc = f"{frame.scene}/{frame.viewpoint} {method.label}"
    output = run_with_progress(frame, [method], desc, progress)[method.label]
    info = {"frame": str(Path(frame_dir).resolve()), "scene": frame.scene, "viewpoint": frame.viewpoint,
            "method": method.label, "config": method.config(), "seconds": output.seconds, "info": output.info,
            "software": software()}
    if frame.has_ground_truth:
        info["metrics"] = summary(output.distance, frame.distance["C"], output.confidence)
    write_prediction(out, frame.scene, frame.viewpoint, output.distance, output.confidence)
    atomic_write_text(prediction_dir(out, frame.scene, frame.viewpoint) / "reconstruction.json",
                      jsonio.dumps(info, indent=2))
    write_method_info(out, {"name": method.label, "description": method.config().get("description", ""),
                            "parameters": method.config()})
    return info
