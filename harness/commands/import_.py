"""The import command: a ``tri360-frame/1`` frame without ground truth from three real equirectangular images.

The rig file (``tri360-rig/1``, documented in ``docs/real-captures.md``) gives the poses of U and R relative to C
in C's camera frame (X right, Y forward, Z up; metres; rotation = C-from-camera, columns the camera's axes).  The
imported frame puts C at the world origin with the identity rotation, so world = C's frame.  Images may be JPEG
or PNG (anything OpenCV decodes), any size with W = 2H, all three the same size; ``width`` resizes them
(area-averaged) first.  ``frame.json``'s ``renderer`` records the sources (paths and SHA-256) and the rig file.
A camera's ``photometric`` record in the rig file (``cameras.<C|U|R>.photometric``,
:class:`harness.data.photometric.Photometric`: every key, each valid) is carried over into the frame's
``frame.json``; a malformed one is refused, naming the rig file, the camera and the key.
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import cv2
import numpy as np

from harness.commands.render import max_width
from harness.data.errors import FrameError, UserError
from harness.data.frame import Frame, write_frame
from harness.data.images import read_png
from harness.data.names import check_name
from harness.data.outputs import check_output, mark_output
from harness.data.photometric import Photometric
from harness.data.provenance import software
from reconstruction.camera.rig import CAMERA_NAMES, CameraPose

__all__ = ["RIG_FORMAT", "read_rig", "import_frame"]

RIG_FORMAT = "tri360-rig/1"
MIN_WIDTH = 60  # what the flow backends can process


def _sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


#: what a rig file may hold, at the top, and in each camera: C is the origin of the rig (no pose of its own)
RIG_KEYS = ("format", "cameras", "baseline_m", "name", "description")
CAMERA_KEYS = {"C": ("photometric",), "U": ("position", "rotation", "photometric"),
               "R": ("position", "rotation", "photometric")}


def _no_other_keys(path: Path, where: str, raw: dict, allowed) -> None:
    """Refuse a key of ``raw`` not in ``allowed`` (it would be ignored without a word), naming it."""
    unknown = sorted(str(k) for k in raw if k not in allowed)
    if unknown:
        why = " (C is the rig's origin: its pose is not given)" if where == "cameras.C." else ""
        raise UserError(f"{path}: unknown key(s) {', '.join(where + k for k in unknown)} in the rig file; it holds "
                        f"{', '.join(where + k for k in allowed)}{why}")


def read_rig(path: Path) -> tuple[dict[str, CameraPose], float, dict[str, Photometric], dict]:
    """Read a ``tri360-rig/1`` file -> (poses of C, U, R in C's frame, baseline_m, the cameras' photometric records
    (cameras without one left out), the parsed JSON).

    Raises:
        UserError: naming ``path``: missing, not JSON, wrong format tag, a missing or malformed pose, a malformed
            photometric record (naming the camera and the key), a key the rig file does not hold (naming it).
    """
    path = Path(path)
    try:
        raw = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise UserError(f"{path}: rig file is missing") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise UserError(f"{path}: rig file is not valid JSON ({exc})") from None
    except OSError as exc:
        raise UserError(f"{path}: rig file cannot be read ({exc.strerror or exc})") from None
    if not isinstance(raw, dict) or raw.get("format") != RIG_FORMAT:
        got = raw.get("format") if isinstance(raw, dict) else None
        raise UserError(f"{path}: rig file format must be {RIG_FORMAT!r}, got {got!r}")
    cams = raw.get("cameras")
    if not isinstance(cams, dict) or not all(k in cams for k in ("U", "R")):
        raise UserError(f"{path}: rig file needs 'cameras' with 'U' and 'R' (poses relative to C)")
    _no_other_keys(path, "", raw, RIG_KEYS)
    _no_other_keys(path, "cameras.", cams, CAMERA_NAMES)
    for k in CAMERA_NAMES:
        if isinstance(cams.get(k), dict):
            _no_other_keys(path, f"cameras.{k}.", cams[k], CAMERA_KEYS[k])
    poses = {"C": CameraPose(np.zeros(3), np.eye(3))}
    for k in ("U", "R"):
        c = cams[k]
        try:
            pos = np.asarray(c["position"], dtype=np.float64)
            rot = np.asarray(c.get("rotation", np.eye(3)), dtype=np.float64)
        except (KeyError, TypeError, ValueError, AttributeError):
            raise UserError(f"{path}: cameras.{k} needs 'position' [x, y, z] metres (and optionally "
                            "'rotation', 3x3)") from None
        if pos.shape != (3,) or rot.shape != (3, 3) or not (np.isfinite(pos).all() and np.isfinite(rot).all()):
            raise UserError(f"{path}: cameras.{k}: position must be 3 finite numbers, rotation 3x3 finite")
        if not np.allclose(rot.T @ rot, np.eye(3), atol=1e-5) or abs(np.linalg.det(rot) - 1) > 1e-5:
            raise UserError(f"{path}: cameras.{k}.rotation is not a proper orthonormal rotation")
        poses[k] = CameraPose(pos, rot)
    lengths = [float(np.linalg.norm(poses[k].position)) for k in ("U", "R")]
    baseline = raw.get("baseline_m", sum(lengths) / 2.0)
    if isinstance(baseline, bool) or not isinstance(baseline, (int, float)) or not math.isfinite(baseline) \
            or baseline <= 0:
        raise UserError(f"{path}: baseline_m must be a positive number, got {baseline!r}")
    return poses, float(baseline), _rig_photometric(path, cams), raw


def _rig_photometric(path: Path, cams: dict) -> dict[str, Photometric]:
    """The ``photometric`` records of a rig file's cameras, checked (:meth:`Photometric.from_json`)."""
    out = {}
    for k in CAMERA_NAMES:
        c = cams.get(k)
        if c is None:
            continue
        if not isinstance(c, dict):
            raise UserError(f"{path}: cameras.{k} must be an object, got {type(c).__name__}")
        if "photometric" in c:
            try:
                out[k] = Photometric.from_json(c["photometric"], f"cameras.{k}.photometric")
            except ValueError as exc:
                raise UserError(f"{path}: {exc}") from None
    return out


def _load(path: Path, label: str) -> tuple[np.ndarray, list[int]]:
    try:
        img = read_png(path)
    except FrameError as exc:
        raise UserError(f"{label} image {exc}") from None
    h, w = img.shape[:2]
    if w != 2 * h:
        raise UserError(f"{path}: an equirectangular image needs width == 2 * height, got {w}x{h}")
    return img, [w, h]


def _resized(img: np.ndarray, width: int | None) -> np.ndarray:
    w = img.shape[1]
    if width is None or width == w:
        return img
    return cv2.resize(img, (width, width // 2), interpolation=cv2.INTER_AREA if width < w else cv2.INTER_CUBIC)


def import_frame(images: dict[str, Path], rig: Path, out: Path, width: int | None = None) -> Path:
    """Write a frame without ground truth at ``out`` = ``<data root>/<scene>/<viewpoint>``.

    Args:
        images: path per camera name ("C", "U", "R").
        rig: a ``tri360-rig/1`` file.
        out: the frame directory to write; its parent's parent is the data root (checked with
            :func:`check_output`, kind ``data``).
        width: resize to this width (even, >= 60, at most what this machine can reconstruct:
            :func:`harness.commands.render.max_width`); None keeps the images' size.  The three images must be of one
            size either way.
    Returns:
        The frame directory written.
    Raises:
        UserError: a bad image, size, rig file, name or output location (one line naming it).
    """
    out = Path(out)
    if width is not None and (width < MIN_WIDTH or width % 2):
        raise UserError(f"--width must be even and at least {MIN_WIDTH}, got {width}")
    if width is not None and width > max_width():
        raise UserError(f"--width {width} is more than this machine can reconstruct (at most {max_width()})")
    scene = check_name(out.parent.name, "--out (scene directory)")
    viewpoint = check_name(out.name, "--out (viewpoint directory)")
    root = out.parent.parent
    poses, baseline, photometric, rig_json = read_rig(rig)
    check_output(root, "data", [*images.values(), Path(rig)])
    loaded, sizes = {}, {}
    for name in CAMERA_NAMES:
        loaded[name], sizes[name] = _load(images[name], name)
    shapes = {loaded[n].shape for n in CAMERA_NAMES}
    if len(shapes) != 1:
        raise UserError("the three images differ in size: " + ", ".join(
            f"{n} {sizes[n][0]}x{sizes[n][1]} ({images[n]})" for n in CAMERA_NAMES))
    loaded = {n: _resized(loaded[n], width) for n in CAMERA_NAMES}
    h, w = loaded["C"].shape[:2]
    renderer = {"name": "import", "sources": {n: {"path": str(Path(images[n]).resolve()),
                                                  "sha256": _sha256(images[n]), "size": sizes[n]}
                                              for n in CAMERA_NAMES},
                "rig": {"path": str(Path(rig).resolve()), "sha256": _sha256(rig), "name": rig_json.get("name", "")},
                "software": software()}
    frame = Frame(scene=scene, viewpoint=viewpoint, width=w, height=h, baseline_m=baseline, cameras=poses,
                  images=loaded, renderer=renderer, photometric=photometric)
    try:
        target = write_frame(frame, root)
    except FrameError as exc:
        raise UserError(f"{rig}: the rig is not usable: {exc}") from None
    mark_output(root, "data")
    return target
