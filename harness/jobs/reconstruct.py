"""The reconstruct job: per-pixel distance of camera C for one frame, one EXR per variant."""

from __future__ import annotations

import json
from pathlib import Path

from tqdm import tqdm

from harness.data.errors import UserError
from harness.data.frame import atomic_write_text, read_frame, write_distance_exr
from reconstruction.methods.flow_pipeline import Reconstruction, available_variants, reconstruct
from reports.metrics import summary


def check_variants(names: list[str] | None) -> list[str]:
    known = available_variants()
    names = known if names is None else names
    bad = [n for n in names if n not in known]
    if bad:
        raise UserError(f"unknown variant(s) {', '.join(bad)} (known: {', '.join(known)})")
    return names


def run_with_progress(frame, flow: str, rectify: bool, variants: list[str], desc: str) -> Reconstruction:
    """:func:`reconstruct` with a stage progress bar; ValueError (e.g. oracle without GT) -> UserError."""
    stages = 3 + len([v for v in variants if v != "average"])
    with tqdm(total=stages, desc=desc, unit="stage", leave=False) as bar:
        def on_stage(name):
            bar.set_postfix_str(name)
            bar.update(1)
        try:
            return reconstruct(frame, flow=flow, rectify=rectify, variants=variants, on_stage=on_stage)
        except ValueError as exc:
            raise UserError(str(exc)) from None


def reconstruct_to(frame_dir: Path, out: Path, flow: str, rectify: bool, variants: list[str]) -> dict:
    """Reconstruct one frame and write ``<variant>.distance.exr`` and ``reconstruction.json`` into ``out``.

    Returns:
        The ``reconstruction.json`` contents (frame, flow, seconds, LM iterations, metrics if GT exists).
    """
    frame = read_frame(frame_dir)
    result = run_with_progress(frame, flow, rectify, variants, f"{frame.scene}/{frame.viewpoint}")
    out.mkdir(parents=True, exist_ok=True)
    for name in variants:
        write_distance_exr(out / f"{name}.distance.exr", result.distance[name])
    info = {"frame": str(frame_dir), "scene": frame.scene, "viewpoint": frame.viewpoint, "flow": flow,
            "rectify": rectify, "seconds": result.seconds, "lm_iterations": result.iterations}
    if frame.has_ground_truth:
        info["metrics"] = {name: summary(result.distance[name], frame.distance["C"]) for name in variants}
    atomic_write_text(out / "reconstruction.json", json.dumps(info, indent=2) + "\n")
    return info
