"""The perturb command: derived frames with calibration error and imaging defects
(:mod:`harness.commands.parts.perturbations`).

For every frame under a data root, writes ``<out>/<scene>/<viewpoint>/`` with the perturbed images and told poses,
the source's ground-truth distance maps unchanged, and in ``frame.json``'s ``renderer`` a ``perturbation`` record:
the source frame (its real path and a SHA-256 over its files, :func:`source_record`), the seed, every perturbation
applied (in :data:`~harness.commands.parts.perturbations.ORDER`) with its level and what was drawn per camera, and
-- when poses were perturbed -- the true poses of U and R.

Pose perturbations change only what the method is *told* (the poses in ``frame.json``); the images keep the true
poses.  C's pose is never perturbed (U and R are calibrated relative to C), so C's distance map -- the one scored --
stays exact.  U's and R's distance maps stay those of their *true* poses (``perturbation.true_cameras``), not of
the told ones.  The true poses are the source's own true poses when it records them (a captured twin's
``renderer.condition.true_cameras``, an earlier perturbation's ``true_cameras``: :func:`true_rig`), else its told
ones.

The source's photometric records (``cameras.<name>.photometric``, a captured twin's cameras) are kept: each
describes the camera that recorded the source image, and the image perturbations of ``applied`` act on that image,
in their order, after it.  Deterministic: the same source, perturbations and seed give byte-identical frames.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

from harness.commands.evaluate import select_frames
from harness.commands.parts import perturbations as P
from harness.data.errors import FrameError, UserError
from harness.data.frame import Frame, find_frames, frame_dir, read_frame, validate_metadata, write_frame
from harness.data.outputs import check_output, mark_output, staged_directory
from harness.data.provenance import software
from reconstruction.camera.rig import CAMERA_NAMES, CameraPose

__all__ = ["parse_applies", "perturb_frame", "checked_perturbation", "perturb_root", "perturb_frames", "frame_hash",
           "source_record", "true_rig"]


def parse_applies(items: list[str], option: str = "--apply") -> list[tuple[str, float | int]]:
    """``["noise=2", "jpeg=80"]`` -> ``[(kind, level), ...]`` in application order.

    Raises:
        UserError: naming ``option``: not KIND=LEVEL, an unknown kind, a bad level, a kind given twice, none given.
    """
    if not items:
        raise UserError(f"{option}: give at least one KIND=LEVEL (kinds: {', '.join(P.ORDER)})")
    found: dict[str, float | int] = {}
    for item in items:
        kind, sep, text = item.partition("=")
        if not sep:
            raise UserError(f"{option} {item!r}: expected KIND=LEVEL (kinds: {', '.join(P.ORDER)})")
        kind = kind.strip()
        try:
            level = P.parse_level(kind, text.strip())
        except ValueError as exc:
            raise UserError(f"{option} {item!r}: {exc}") from None
        if kind in found:
            raise UserError(f"{option} {item!r}: {kind} is given twice")
        found[kind] = level
    return [(k, found[k]) for k in P.ORDER if k in found]


def frame_hash(directory: Path) -> str:
    """SHA-256 (hex) over the names and bytes of a frame directory's files, in name order."""
    h = hashlib.sha256()
    for p in sorted(Path(directory).iterdir()):
        if p.is_file() and not p.name.startswith("."):
            h.update(p.name.encode() + b"\0")
            h.update(p.read_bytes())
    return h.hexdigest()


def source_record(directory: Path) -> dict:
    """What a derived frame records of its source frame directory: ``{"path": its real path, "sha256":
    frame_hash(directory)}``."""
    return {"path": str(Path(directory).resolve()), "sha256": frame_hash(directory)}


def true_rig(frame: Frame) -> tuple[dict[str, CameraPose], float]:
    """The true poses of ``frame``'s cameras and its true baseline.

    A captured twin records them in ``renderer.condition`` and a frame perturbed with calibration error in
    ``renderer.perturbation`` (``true_cameras`` of U and R, ``true_baseline_m``; the condition's first); C's told
    pose is exact in both.  A frame that records neither is told its true poses.

    Raises:
        FrameError: naming the frame's ``frame.json`` and the record, for a record that is malformed or describes
            an impossible rig (the checks of :func:`harness.data.frame.validate_metadata`).
    """
    meta_path = Path(frame.path or Path(frame.scene) / frame.viewpoint) / "frame.json"
    for where in ("condition", "perturbation"):
        record = frame.renderer.get(where)
        if not (isinstance(record, dict) and "true_cameras" in record):
            continue
        true = record["true_cameras"]
        if not (isinstance(true, dict) and set(true) == {"U", "R"} and "true_baseline_m" in record):
            raise FrameError(f"{meta_path}: renderer.{where}: true_cameras must hold the poses of U and R, and "
                             "true_baseline_m the true baseline")
        meta = frame.metadata()
        meta["cameras"] = {**meta["cameras"], **true}
        meta["baseline_m"] = record["true_baseline_m"]
        try:
            cameras = validate_metadata(meta, meta_path)
        except FrameError as exc:
            reason = str(exc).removeprefix(str(meta_path)).lstrip(": ")
            where += ".true_cameras"
            if reason.startswith("(cameras."):  # a pose's own problem: name the camera in the record
                camera, reason = reason.removeprefix("(cameras.").split("): ", 1)
                where += f".{camera}"
            raise FrameError(f"{meta_path}: renderer.{where}: {reason}") from None
        return cameras, float(meta["baseline_m"])
    return dict(frame.cameras), float(frame.baseline_m)


def perturb_frame(frame: Frame, applies: list[tuple[str, float | int]], seed: int, source: dict) -> Frame:
    """A new :class:`Frame`: ``frame`` with ``applies`` done to it (see the module doc); ``frame`` is unchanged.

    Args:
        frame: the source frame.
        applies: ``(kind, level)`` pairs (:func:`parse_applies`), applied in :data:`perturbations.ORDER`.
        seed: the random seed (each kind and camera has its own stream, :func:`perturbations.generator`).
        source: what the record says of the source (``path``, ``sha256``).

    The result is not validated: a large translation can make ``|U - C|`` and ``|R - C|`` disagree on one baseline
    (:func:`perturb_root` checks every derived frame before writing any).

    Raises:
        FrameError: the source's record of its true poses is malformed (:func:`true_rig`).
    """
    applies = sorted(applies, key=lambda a: P.ORDER.index(a[0]))  # the fixed physical order, whatever the caller's
    cameras = dict(frame.cameras)
    images = {n: frame.images[n].copy() for n in CAMERA_NAMES}
    baseline = frame.baseline_m
    records = []
    glare_source = None
    for kind, level in applies:
        drawn = {}
        for name in CAMERA_NAMES:
            rng = P.generator(seed, kind, name)
            if kind in ("rotation", "translation"):
                if name == "C":
                    continue
                fn = P.perturb_pose_rotation if kind == "rotation" else P.perturb_pose_translation
                cameras[name], drawn[name] = fn(cameras[name], level, rng)
            elif kind == "glare":
                if glare_source is None:
                    glare_source = P.brightest_bearing(frame.images["C"], frame.cameras["C"])
                images[name], drawn[name] = P.glare(images[name], level, frame.cameras[name], glare_source)
            else:
                images[name], drawn[name] = P.IMAGE_OPS[kind](images[name], level, rng)
        if kind == "translation":
            told = [float(((cameras[k].position - cameras["C"].position) ** 2).sum() ** 0.5) for k in ("U", "R")]
            baseline = sum(told) / 2.0
            drawn["baseline_m"] = baseline
        records.append({"kind": kind, "level": level, "unit": P.KINDS[kind], "seed": int(seed), "drawn": drawn})
    record = {"source": dict(source), "seed": int(seed), "applied": records, "software": software()}
    if any(k in ("rotation", "translation") for k, _ in applies):
        true_cameras, true_baseline = true_rig(frame)
        record["true_cameras"] = {n: true_cameras[n].to_json() for n in ("U", "R")}
        record["true_baseline_m"] = true_baseline
    if "perturbation" in frame.renderer:
        record["source"]["perturbation"] = frame.renderer["perturbation"]
    renderer = {k: v for k, v in frame.renderer.items() if k != "perturbation"}
    renderer["perturbation"] = record
    return Frame(scene=frame.scene, viewpoint=frame.viewpoint, width=frame.width, height=frame.height,
                 baseline_m=baseline, cameras=cameras, images=images, distance=dict(frame.distance),
                 renderer=renderer, photometric=dict(frame.photometric))


def checked_perturbation(d: Path, frame: Frame, applies: list[tuple[str, float | int]], seed: int, out: Path,
                         option: str = "--apply") -> Frame:
    """:func:`perturb_frame` of the frame read from directory ``d``, its metadata checked as if written to data
    root ``out`` (a perturbed told rig may be impossible: ``|U - C|`` and ``|R - C|`` no longer on one baseline).

    Raises:
        UserError: naming ``option`` and the perturbations, the frame and why its told rig is impossible.
        FrameError: the source's record of its true poses is malformed (:func:`true_rig`).
    """
    new = perturb_frame(frame, applies, seed, source_record(d))
    try:
        validate_metadata(new.metadata(), Path(out) / new.scene / new.viewpoint / "frame.json")
    except FrameError as exc:
        told = ", ".join(f"{k}={v}" for k, v in applies if k in ("rotation", "translation"))
        raise UserError(f"{option} {told}: the told rig of {d} would be impossible ({exc})") from None
    return new


def perturb_root(data: Path, out: Path, applies: list[tuple[str, float | int]], seed: int) -> list[Path]:
    """Perturb every frame under data root (or frame directory) ``data`` into data root ``out``.

    Every source frame is read and checked before anything is written (two frame directories naming the same
    scene and viewpoint are refused, as ``evaluate`` refuses them); the whole data root is built in a hidden
    staging directory beside ``out`` and swapped in at the end, so an interrupted run leaves the previous ``out``
    as it was, never a mix of old and new frames.

    Returns:
        The frame directories written.
    Raises:
        UserError: no frames under ``data``, a malformed frame (named), an unsafe name, two frames with one
            identity (named), an unusable ``out`` (:func:`check_output`), or a perturbed rig that would be
            impossible (named).
    """
    data, out = Path(data), Path(out)
    if not data.is_dir():
        raise UserError(f"{data}: no such data root (a directory of <scene>/<viewpoint>/ frames)")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise UserError(f"--seed must be a non-negative integer, got {seed!r}")
    dirs = find_frames(data)
    if not dirs:
        raise UserError(f"{data}: no frames found (no <scene>/<viewpoint>/frame.json under it)")
    check_output(out, "data", [data, *dirs])
    dirs = [r.path for r in select_frames(data)]  # names checked, one frame per scene/viewpoint
    return perturb_frames(dirs, out, applies, seed)


def perturb_frames(dirs: list[Path], out: Path, applies: list[tuple[str, float | int]], seed: int) -> list[Path]:
    """Perturb the frames of ``dirs`` (frame directories, one per scene/viewpoint, already checked) into data root
    ``out``, which afterwards holds exactly them (built in a staging directory and swapped in, as
    :func:`perturb_root`).

    Raises:
        UserError: a malformed frame (named), or a perturbed rig that would be impossible (named).
    """
    out = Path(out)
    frames = [(d, read_frame(d)) for d in dirs]
    derived = [checked_perturbation(d, frame, applies, seed, out) for d, frame in frames]  # all before writing
    with staged_directory(out) as stage:
        for new in derived:
            try:
                write_frame(new, stage)
            except FrameError as exc:
                raise UserError(f"perturbed frame {new.scene}/{new.viewpoint} is invalid: {exc}") from None
        mark_output(stage, "data")
    return [frame_dir(out, new.scene, new.viewpoint) for new in derived]
