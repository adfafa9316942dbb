"""The export command: frames written in the dataset layout a learned 360-degree stereo method reads.

``tri360 export DATA --format 3d60|helvipad|360sd|deep360 --out DIR`` writes every frame of ``DATA`` (or of a suite's
split) in the layout of :data:`harness.data.layouts.LAYOUTS`, with the conversions it needs (distance, angular
disparity, 16-bit scales, the 360SD turn, Deep360's Cassini-rectified pairs), and ``DIR/manifest.json``
(``tri360-export/1``) mapping every file back to its frame: scene, viewpoint, camera, what it holds, the source frame
directory.  ``tri360 score PREDS --export DIR`` reads the manifest to bring a method's predictions back
(:func:`harness.commands.score.score_export`).

Every frame is read and checked before anything is written: a rig the layout cannot hold (U not straight above C, R
not straight right of C, cameras not parallel: :func:`harness.data.layouts.rig_problem`) or a frame without ground
truth (the peers' loaders find frames through their depth or disparity files) is refused with one line. The whole
export is built in a staging directory beside ``DIR`` and swapped in (``DIR``: absent, empty or an export tri360
wrote).
"""

from __future__ import annotations

from pathlib import Path

from harness.commands.evaluate import select_frames
from harness.data import jsonio
from harness.data.atomic import atomic_write_text
from harness.data.errors import UserError
from harness.data.frame import Frame, read_frame
from harness.data.images import write_png
from harness.data.layouts import (
    ENCODINGS,
    LAYOUTS,
    MANIFEST,
    MANIFEST_FORMAT,
    frame_paths,
    rig_problem,
    to_cassini,
    to_layout,
    to_rectified,
    turn,
)
from harness.data.outputs import check_output, mark_output, staged_directory
from harness.data.provenance import software
from reconstruction.camera.rig import CAMERA_NAMES

__all__ = ["export", "export_frames"]


def _check(layout_name: str, frame: Frame, has_ground_truth: bool) -> None:
    """Refuse (UserError, one line naming the frame) what the layout cannot hold."""
    layout = LAYOUTS[layout_name]
    where = frame.path / "frame.json" if frame.path else f"{frame.scene}/{frame.viewpoint}"
    why = rig_problem(layout, frame.cameras)
    if why:
        raise UserError(f"{where}: the {layout_name} layout cannot hold this rig: {why}")
    if not has_ground_truth:
        raise UserError(f"{where}: no ground truth (no C.distance.exr): the {layout_name} loaders find frames "
                        "through their depth or disparity files, so tri360 exports only frames with ground truth")


def _write_frame(stage: Path, layout_name: str, frame: Frame, split: str | None, index: int) -> dict:
    """Write one frame's files under ``stage``; its manifest entry."""
    layout = LAYOUTS[layout_name]
    fields = frame_paths(layout, split, frame.scene, frame.viewpoint, index)
    base = {c: float(((frame.cameras[c].position - frame.cameras["C"].position) ** 2).sum() ** 0.5)
            for c in ("U", "R") if c in frame.cameras}
    b_u = base["U"]
    files = []
    for cam, template in layout.images.items():
        rel = template.format(**fields)
        write_png(stage / rel, turn(frame.images[cam], layout.turned))
        files.append({"path": rel, "camera": cam, "holds": "image"})
    for im in layout.rectified:
        rel = im.path.format(**fields)
        write_png(stage / rel, to_cassini(frame.images[im.camera], im.partner))
        files.append({"path": rel, "camera": im.camera, "holds": "image", "rectified_with": im.partner})
    invalid = {}
    for m in layout.maps:
        enc = ENCODINGS[m.encoding]
        rel = m.path.format(**fields) + enc.suffix
        if m.partner:
            values = to_rectified(m.quantity, frame.distance[m.camera], m.partner, base[m.partner])
        else:
            values = turn(to_layout(m.quantity, frame.distance[m.camera], b_u), layout.turned)
        enc.write(stage / rel, values)
        back = enc.read(stage / rel)
        invalid[rel] = int((back <= 0).sum())
        files.append({"path": rel, "camera": m.camera, "holds": m.quantity, "encoding": m.encoding,
                      **({"rectified_with": m.partner} if m.partner else {})})
    return {"scene": frame.scene, "viewpoint": frame.viewpoint, "source": str(Path(frame.path).resolve()),
            "width": frame.width, "height": frame.height, "baseline_m": frame.baseline_m, "baseline_u_m": b_u,
            **({"baseline_r_m": base["R"]} if "R" in base else {}),
            "fields": fields, "files": files, "invalid_pixels": invalid}


def export_frames(dirs: list[Path], layout_name: str, out: Path, split: str | None = None) -> list[dict]:
    """Export the frame directories ``dirs`` (checked, one per scene/viewpoint) into ``out`` (already checked by
    :func:`harness.data.outputs.check_output`); returns the manifest's frame entries.

    Raises:
        UserError: a malformed frame (named), a rig or frame the layout cannot hold (named).
    """
    if layout_name not in LAYOUTS:
        raise UserError(f"--format {layout_name}: unknown layout (known: {', '.join(LAYOUTS)})")
    layout = LAYOUTS[layout_name]
    for d in dirs:  # every frame checked before anything is written; none is kept (a split holds thousands)
        _check(layout_name, read_frame(d, load_distance=False),
               all((Path(d) / f"{k}.distance.exr").is_file() for k in CAMERA_NAMES))
    entries = []
    with staged_directory(out) as stage:
        for i, d in enumerate(dirs):
            entries.append(_write_frame(stage, layout_name, read_frame(d), split, i))
        for folder in layout.folders:
            (stage / folder.format(split=layout.split_dir(split))).mkdir(parents=True, exist_ok=True)
        if layout.file_list:
            lines = [layout.line.format(**e["fields"]) for e in entries]
            atomic_write_text(stage / layout.file_list.format(split=layout.split_dir(split)), "\n".join(lines) + "\n")
        manifest = {"format": MANIFEST_FORMAT, "layout": layout_name, "peer": layout.peer, "split": split,
                    "turned": layout.turned, "conventions": {
                        "distance": "metres along the ray from the camera centre (the layouts' 'depth'); 0 = none",
                        "disparity": "degrees, C's pixel with respect to U: atan2(b sin(a), r - b cos(a)), a = angle "
                                     "from C's up axis; 0 = none",
                        "disparity_px": "Cassini pixels (deep360), C's pixel with respect to the pair's partner, "
                                        "0 = no surface, NaN = no ground truth"},
                    "software": software(), "frames": entries}
        atomic_write_text(stage / MANIFEST, jsonio.dumps(manifest, indent=1))
        mark_output(stage, "export")
    return entries


def export(data: Path, layout_name: str, out: Path, dirs: list[Path] | None = None,
           split: str | None = None) -> list[dict]:
    """Export every frame under data root (or frame directory) ``data`` -- or the frame directories ``dirs`` of a
    suite's split -- in layout ``layout_name`` into ``out``.

    Raises:
        UserError: unknown layout, no frames, a malformed frame, an unusable ``out`` (:func:`check_output`), a rig
            or frame the layout cannot hold; nothing is written then.
    """
    data, out = Path(data), Path(out)
    if layout_name not in LAYOUTS:
        raise UserError(f"--format {layout_name}: unknown layout (known: {', '.join(LAYOUTS)})")
    refs = select_frames(data) if dirs is None else None
    dirs = [r.path for r in refs] if dirs is None else list(dirs)
    check_output(out, "export", [data, *dirs])
    return export_frames(dirs, layout_name, out, split)
