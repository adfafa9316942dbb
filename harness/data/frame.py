"""The on-disk frame format ``tri360-frame/1``: read, write and validate.

::

    <root>/<scene>/<viewpoint>/
      frame.json                       # metadata
      C.png  U.png  R.png              # 8-bit sRGB equirectangular, W x H
      C.distance.exr  U.distance.exr  R.distance.exr   # float32 channel "distance", metres, +inf = no surface

Distance files are optional (real captures have no ground truth).  Every reader validates and raises
:class:`FrameError` with one message naming the file and what is wrong.  :func:`read_frame` reads the pixels;
:func:`read_frame_info` reads ``frame.json`` only and looks at which files are there (for listing and selecting
frames, and checking a data root before the work).  :func:`write_frame` runs the same
checks *before* it writes anything, so it never produces a frame that :func:`read_frame` refuses.  Writes
are atomic (:mod:`harness.data.atomic`): a frame is assembled in a hidden sibling directory and swapped into
place, so an interrupted write never leaves a directory that looks like a complete frame, and concurrent
writers of one frame each leave a complete frame (the last one wins).

Besides shapes and types, the rig itself is checked: finite numbers, orthonormal proper rotations, no two
cameras closer than :data:`MIN_CAMERA_SEPARATION_M`, no colinear or nearly colinear cameras (the baselines
``U - C`` and ``R - C`` at least :data:`MIN_BASELINE_ANGLE_DEG` from one line), and ``|U - C|`` and ``|R - C|``
within :func:`baseline_tolerance_m` of ``baseline_m``.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from harness.data.atomic import atomic_directory, atomic_write_text
from harness.data.errors import FrameError
from harness.data.exr import read_distance_exr, write_distance_exr
from harness.data.images import read_png, require_file, write_png
from harness.data.names import MAX_NAME_LENGTH, NAME_CHARACTERS, is_safe_name
from harness.data.photometric import Photometric
from reconstruction.camera.image_ops import vector_angle_deg
from reconstruction.camera.rig import CAMERA_NAMES, CameraPose

__all__ = [
    "FORMAT",
    "Frame",
    "FrameError",
    "FrameInfo",
    "MIN_CAMERA_SEPARATION_M",
    "baseline_tolerance_m",
    "validate_metadata",
    "read_frame",
    "read_frame_info",
    "write_frame",
    "frame_dir",
    "is_complete",
    "find_frames",
]

FORMAT = "tri360-frame/1"
MIN_CAMERA_SEPARATION_M = 1e-3  # two camera centres closer than this (metres) are "the same place"
MIN_BASELINE_ANGLE_DEG = 20.0  # U - C and R - C closer than this to one line (degrees) are colinear cameras
BASELINE_REL_TOL = 0.01  # |U - C| and |R - C| may differ from baseline_m by 1 % ...
BASELINE_ABS_TOL_M = 1e-3  # ... or by 1 mm, whichever is larger
ROTATION_TOL = 1e-5  # max |R^T R - I| entry and |det R - 1|


@dataclass
class Frame:
    """One rig placement in one scene.

    Attributes:
        scene, viewpoint: names (the two directory levels under the data root).
        width, height: image size in pixels, width == 2 * height.
        baseline_m: rig baseline, metres.
        cameras: pose per camera name ("C", "U", "R").
        images: (H, W, 3) uint8 sRGB image per camera name, RGB channel order.
        distance: (H, W) float32 Euclidean distance per camera name, metres, +inf where nothing is hit;
            empty when the frame has no ground truth.
        renderer: free-form provenance.
        path: directory the frame was read from, if any.
        photometric: per camera name, what the camera did to the light (:class:`harness.data.photometric.
            Photometric`; ``frame.json``'s ``cameras.<name>.photometric``); a camera without one is ideal.
    """

    scene: str
    viewpoint: str
    width: int
    height: int
    baseline_m: float
    cameras: dict[str, CameraPose]
    images: dict[str, np.ndarray]
    distance: dict[str, np.ndarray] = field(default_factory=dict)
    renderer: dict = field(default_factory=dict)
    path: Path | None = None
    photometric: dict[str, Photometric] = field(default_factory=dict)

    @property
    def has_ground_truth(self) -> bool:
        return all(name in self.distance for name in CAMERA_NAMES)

    def metadata(self) -> dict:
        return {
            "format": FORMAT,
            "scene": self.scene,
            "viewpoint": self.viewpoint,
            "width": int(self.width),
            "height": int(self.height),
            "baseline_m": float(self.baseline_m),
            "cameras": {name: {**self.cameras[name].to_json(),
                               **({"photometric": self.photometric[name].to_json()}
                                  if name in self.photometric else {})} for name in CAMERA_NAMES},
            "renderer": self.renderer,
        }


@dataclass(frozen=True)
class FrameInfo:
    """A frame directory as its ``frame.json`` and its file names describe it, no pixel read (:func:`read_frame_info`).

    Attributes:
        path: the frame directory.
        scene, viewpoint: names (validated as :func:`read_frame` does).
        width, height: image size in pixels, width == 2 * height.
        has_ground_truth: the directory holds a distance file for every camera (otherwise it holds none); the
            maps themselves are not read, so whether they decode and hold a finite distance is not known.
    """

    path: Path
    scene: str
    viewpoint: str
    width: int
    height: int
    has_ground_truth: bool


# --------------------------------------------------------------------------------------------- validation


def baseline_tolerance_m(baseline_m: float) -> float:
    """How far (metres) ``|U - C|`` or ``|R - C|`` may be from ``baseline_m``: 1 % of it or 1 mm, the larger."""
    return max(BASELINE_REL_TOL * baseline_m, BASELINE_ABS_TOL_M)


def _require(cond: bool, where, msg: str) -> None:
    if not cond:
        raise FrameError(f"{where}: {msg}")


def _parse_pose(meta_path: Path, name: str, raw) -> CameraPose:
    where = f"{meta_path} (cameras.{name})"
    _require(isinstance(raw, dict), where, "must be an object with 'position' and 'rotation'")
    try:
        pos = np.asarray(raw["position"], dtype=np.float64)
        rot = np.asarray(raw["rotation"], dtype=np.float64)
    except KeyError as exc:
        raise FrameError(f"{where}: missing key {exc}") from None
    except (TypeError, ValueError):
        raise FrameError(f"{where}: position/rotation must be numbers") from None
    _require(pos.shape == (3,), where, f"position must have 3 numbers, got shape {pos.shape}")
    _require(bool(np.isfinite(pos).all()), where, "position is not finite")
    _require(rot.shape == (3, 3), where, f"rotation must be 3x3, got shape {rot.shape}")
    _require(bool(np.isfinite(rot).all()), where, "rotation is not finite")
    _require(bool(np.allclose(rot.T @ rot, np.eye(3), rtol=0.0, atol=ROTATION_TOL)), where,
             "rotation is not orthonormal")
    _require(abs(np.linalg.det(rot) - 1.0) < ROTATION_TOL, where, "rotation is not proper (det != +1)")
    return CameraPose(pos, rot)


def _check_rig(meta_path: Path, cameras: dict[str, CameraPose], baseline_m: float) -> None:
    """Refuse rigs that cannot be: coincident cameras, or positions that contradict ``baseline_m``."""
    for i, a in enumerate(CAMERA_NAMES):
        for b in CAMERA_NAMES[i + 1:]:
            gap = float(np.linalg.norm(cameras[a].position - cameras[b].position))
            _require(gap >= MIN_CAMERA_SEPARATION_M, meta_path,
                     f"impossible rig: cameras {a} and {b} coincide ({gap * 1000:.3g} mm apart, "
                     f"minimum {MIN_CAMERA_SEPARATION_M * 1000:g} mm)")
    t_u, t_r = (cameras[k].position - cameras["C"].position for k in ("U", "R"))
    angle = vector_angle_deg(t_u, t_r)
    _require(MIN_BASELINE_ANGLE_DEG <= angle <= 180.0 - MIN_BASELINE_ANGLE_DEG, meta_path,
             f"impossible rig: U - C and R - C are {angle:.3g} degrees apart, colinear cameras (the two baselines "
             f"must be {MIN_BASELINE_ANGLE_DEG:g} to {180 - MIN_BASELINE_ANGLE_DEG:g} degrees apart; 90 in an L rig)")
    tol = baseline_tolerance_m(baseline_m)
    for k in ("U", "R"):
        gap = float(np.linalg.norm(cameras[k].position - cameras["C"].position))
        _require(abs(gap - baseline_m) <= tol, meta_path,
                 f"impossible rig: |{k} - C| = {gap:.6g} m contradicts baseline_m = {baseline_m:.6g} m "
                 f"(tolerance {tol:.3g} m)")


def validate_metadata(meta: dict, meta_path: Path) -> dict[str, CameraPose]:
    """Check a parsed ``frame.json`` and return the camera poses.

    Raises:
        FrameError: naming ``meta_path``, on the first problem: wrong format tag, missing or mistyped key,
            unusable scene/viewpoint name, size not W x W/2, baseline not positive and finite, a camera
            missing or with a non-finite / non-orthonormal pose, or an impossible rig (:func:`_check_rig`).
    """
    _require(isinstance(meta, dict), meta_path, "must be a JSON object")
    _require(meta.get("format") == FORMAT, meta_path, f"format must be {FORMAT!r}, got {meta.get('format')!r}")
    for key, typ in (("scene", str), ("viewpoint", str), ("width", int), ("height", int),
                     ("baseline_m", (int, float)), ("cameras", dict)):
        _require(key in meta, meta_path, f"missing key {key!r}")
        _require(isinstance(meta[key], typ) and not isinstance(meta[key], bool), meta_path,
                 f"{key!r} has the wrong type ({type(meta[key]).__name__})")
    for key in ("scene", "viewpoint"):
        _require(is_safe_name(meta[key]), meta_path,
                 f"{key} {meta[key]!r} cannot be a directory name (use only {NAME_CHARACTERS}, no leading dot, "
                 f"no '..', at most {MAX_NAME_LENGTH} characters)")
    w, h = meta["width"], meta["height"]
    _require(w > 0 and h > 0, meta_path, f"width and height must be positive, got {w}x{h}")
    _require(w == 2 * h, meta_path, f"equirectangular frames need width == 2*height, got {w}x{h}")
    b = float(meta["baseline_m"])
    _require(math.isfinite(b) and b > 0, meta_path, f"baseline_m must be positive and finite, got {b}")
    for name in CAMERA_NAMES:
        _require(name in meta["cameras"], meta_path, f"cameras.{name} is missing")
    if "renderer" in meta:
        _require(isinstance(meta["renderer"], dict), meta_path, "'renderer' must be an object")
    cameras = {name: _parse_pose(meta_path, name, meta["cameras"][name]) for name in CAMERA_NAMES}
    _check_rig(meta_path, cameras, b)
    parse_photometric(meta, meta_path)
    return cameras


def parse_photometric(meta: dict, meta_path: Path) -> dict[str, Photometric]:
    """The cameras' photometric records of a ``frame.json`` (cameras without one are left out).

    Raises:
        FrameError: naming ``meta_path`` and the camera, for a malformed record.
    """
    out = {}
    for name in CAMERA_NAMES:
        raw = meta["cameras"][name]
        if isinstance(raw, dict) and "photometric" in raw:
            try:
                out[name] = Photometric.from_json(raw["photometric"], f"cameras.{name}.photometric")
            except ValueError as exc:
                raise FrameError(f"{meta_path}: {exc}") from None
    return out


def _check_distance(where: Path, d: np.ndarray, w: int, h: int) -> None:
    """Ground-truth distance as :func:`read_frame` will accept it: (h, w), > 0, +inf allowed, no NaN/-inf."""
    d = np.asarray(d)
    _require(d.shape == (h, w), where, f"distance map is {d.shape}, frame is (H, W) = ({h}, {w})")
    _require(np.issubdtype(d.dtype, np.floating), where, f"distance map must be floating point, got {d.dtype}")
    _require(not bool(np.isnan(d).any()), where, "distance map contains NaN")
    _require(bool((d > 0).all()), where, f"distances must be positive (found min {float(np.min(d)):.4g} m)")


def _check_frame(frame: Frame, target: Path) -> str:
    """Everything :func:`write_frame` needs checked before it touches the disk -> the frame.json text."""
    meta_path = target / "frame.json"
    missing = [n for n in CAMERA_NAMES if n not in frame.cameras or n not in frame.images]
    _require(not missing, meta_path, f"no pose or image for camera(s) {', '.join(missing)}")
    try:
        meta = frame.metadata()
    except (TypeError, ValueError) as exc:
        raise FrameError(f"{meta_path}: cannot be written ({exc})") from None
    validate_metadata(meta, meta_path)
    for name in CAMERA_NAMES:
        img = np.asarray(frame.images[name])
        _require(img.dtype == np.uint8 and img.shape == (frame.height, frame.width, 3), target / f"{name}.png",
                 f"image must be ({frame.height}, {frame.width}, 3) uint8, got {img.shape} {img.dtype}")
    present = [n for n in CAMERA_NAMES if n in frame.distance]
    _require(len(present) in (0, len(CAMERA_NAMES)), target,
             f"ground truth for {', '.join(present)} only: give a distance map for every camera or none")
    for name in present:
        _check_distance(target / f"{name}.distance.exr", frame.distance[name], frame.width, frame.height)
    try:
        return json.dumps(meta, indent=2, allow_nan=False) + "\n"
    except (TypeError, ValueError) as exc:  # e.g. a NaN or a numpy object in the renderer provenance
        raise FrameError(f"{meta_path}: metadata is not plain JSON ({exc})") from None


# ----------------------------------------------------------------------------------------------- read/write


def _read_metadata(directory: Path) -> tuple[dict, dict[str, CameraPose]]:
    """``directory``'s parsed and validated ``frame.json`` and its camera poses (:func:`validate_metadata`).

    Raises:
        FrameError: naming ``frame.json``: missing, not a regular file, unreadable, not JSON, or malformed.
    """
    meta_path = directory / "frame.json"
    if not meta_path.exists():
        raise FrameError(f"{meta_path}: file is missing (not a tri360 frame directory)")
    if not meta_path.is_file():
        raise FrameError(f"{meta_path}: is not a regular file")
    try:
        meta = json.loads(meta_path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise FrameError(f"{meta_path}: not valid JSON ({exc})") from None
    except OSError as exc:
        raise FrameError(f"{meta_path}: cannot be read ({exc.strerror or exc})") from None
    return meta, validate_metadata(meta, meta_path)


def read_frame(directory: Path, load_distance: bool = True) -> Frame:
    """Read and validate one ``tri360-frame/1`` directory: ``frame.json``, then each camera's image, then (when any
    is there) each camera's distance map, every file once.

    Args:
        directory: the frame directory.
        load_distance: also read (and validate) the distance maps, if present.
    Raises:
        FrameError: naming the offending file, for anything missing or malformed.
    """
    directory = Path(directory)
    meta, cameras = _read_metadata(directory)
    meta_path = directory / "frame.json"
    w, h = meta["width"], meta["height"]
    images, distance = {}, {}
    for name in CAMERA_NAMES:
        p = directory / f"{name}.png"
        img = read_png(p)
        _require(img.shape[:2] == (h, w), p, f"size {img.shape[1]}x{img.shape[0]} != frame.json {w}x{h}")
        images[name] = img
    exr_present = [(directory / f"{n}.distance.exr").exists() for n in CAMERA_NAMES]
    if load_distance and any(exr_present):
        for name in CAMERA_NAMES:
            p = directory / f"{name}.distance.exr"
            d = read_distance_exr(p)
            _require(d.shape == (h, w), p, f"size {d.shape[1]}x{d.shape[0]} != frame.json {w}x{h}")
            distance[name] = d
    return Frame(scene=meta["scene"], viewpoint=meta["viewpoint"], width=w, height=h,
                 baseline_m=float(meta["baseline_m"]), cameras=cameras, images=images, distance=distance,
                 renderer=meta.get("renderer", {}), path=directory, photometric=parse_photometric(meta, meta_path))


def read_frame_info(directory: Path) -> FrameInfo:
    """What one frame directory says of itself, reading only ``frame.json`` (validated as :func:`read_frame` does)
    and looking at which files are there: no image or distance map is opened.

    Raises:
        FrameError: naming the file: a missing or malformed ``frame.json``, a camera's image missing or not a
            regular file, or a distance file missing for a camera when another camera has one (:func:`read_frame`
            would refuse each of these the same way).
    """
    directory = Path(directory)
    meta, _ = _read_metadata(directory)
    for name in CAMERA_NAMES:
        require_file(directory / f"{name}.png")
    exr = [directory / f"{n}.distance.exr" for n in CAMERA_NAMES]
    present = [p.exists() for p in exr]
    if any(present) and not all(present):
        raise FrameError(f"{exr[present.index(False)]}: file is missing (a frame has a distance map for every "
                         "camera or for none)")
    return FrameInfo(path=directory, scene=meta["scene"], viewpoint=meta["viewpoint"], width=meta["width"],
                     height=meta["height"], has_ground_truth=all(present))


def frame_dir(root: Path, scene: str, viewpoint: str) -> Path:
    """``<root>/<scene>/<viewpoint>``."""
    return Path(root) / scene / viewpoint


def is_complete(directory: Path) -> bool:
    """True if ``directory`` holds a frame that reads and validates (used to skip finished renders)."""
    try:
        read_frame(directory)
    except FrameError:
        return False
    return True


def write_frame(frame: Frame, root: Path) -> Path:
    """Write ``frame`` atomically to ``<root>/<scene>/<viewpoint>/`` and return that directory.

    Everything is validated first (the checks of :func:`read_frame`); nothing is written for a bad frame.
    The frame is built in a hidden sibling ``.<viewpoint>.partial-<pid>-<token>`` and swapped into place
    (:func:`harness.data.atomic.atomic_directory`), replacing a previous frame there; concurrent writers of
    the same frame never fail because of each other and leave no hidden entries behind.

    Raises:
        FrameError: the frame is invalid (naming the file it would have written).
        OSError: the location is unusable (naming the path), e.g. a file where a directory must go.
    """
    target = frame_dir(root, frame.scene, frame.viewpoint)
    meta_text = _check_frame(frame, target)
    with atomic_directory(target) as tmp:
        for name in CAMERA_NAMES:
            write_png(tmp / f"{name}.png", frame.images[name])
            if name in frame.distance:
                write_distance_exr(tmp / f"{name}.distance.exr", frame.distance[name])
        atomic_write_text(tmp / "frame.json", meta_text)
    return target


def find_frames(root: Path) -> list[Path]:
    """All frame directories (those holding ``frame.json``) under ``root``, sorted; hidden dirs skipped.

    Symbolic links to directories are followed (data roots are often assembled from links), each real
    directory at most once, so a link cycle cannot loop.
    """
    root = Path(root)
    out, seen = [], set()
    for dirpath, dirnames, filenames in os.walk(root, followlinks=True):
        real = os.path.realpath(dirpath)
        if real in seen:
            dirnames[:] = []
            continue
        seen.add(real)
        dirnames[:] = sorted(d for d in dirnames if not d.startswith("."))
        if "frame.json" in filenames:
            out.append(Path(dirpath))
    return sorted(out)
