"""The on-disk frame format ``tri360-frame/1``: read, write and validate.

::

    <root>/<scene>/<viewpoint>/
      frame.json                       # metadata
      C.png  U.png  R.png              # 8-bit sRGB equirectangular, W x H
      C.distance.exr  U.distance.exr  R.distance.exr   # float32 channel "distance", metres, +inf = no surface

Distance files are optional (real captures have no ground truth).  Every reader validates and raises
:class:`FrameError` with one message naming the file and what is wrong.  Writers are atomic: a frame is
assembled in a hidden sibling directory and renamed into place, ``frame.json`` written last, so an
interrupted write never leaves a directory that looks like a complete frame.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
import OpenEXR

from harness.data.errors import FrameError
from reconstruction.camera.rig import CAMERA_NAMES, CameraPose

FORMAT = "tri360-frame/1"
DISTANCE_CHANNEL = "distance"
NO_HIT_THRESHOLD_M = 1e9  # Cycles writes 1e10 for rays that hit nothing; anything above is stored as +inf


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
            "cameras": {name: self.cameras[name].to_json() for name in CAMERA_NAMES},
            "renderer": self.renderer,
        }


# --------------------------------------------------------------------------------------------- atomic io


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same directory, then rename."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".partial")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_write_text(path: Path, text: str) -> None:
    atomic_write_bytes(path, text.encode("utf-8"))


def _atomic_via(path: Path, writer) -> None:
    """Call ``writer(tmp_path)`` for a temporary path beside ``path`` (same suffix), then rename."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.partial.", suffix=path.suffix)
    os.close(fd)
    try:
        writer(tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_distance_exr(path: Path, distance: np.ndarray) -> None:
    """Write an (H, W) distance map (metres, +inf = no surface) as a float32 EXR, channel "distance"."""
    d = np.ascontiguousarray(distance, dtype=np.float32)
    if d.ndim != 2:
        raise FrameError(f"{path}: distance map must be 2-D (H, W), got shape {d.shape}")
    if np.isnan(d).any():
        raise FrameError(f"{path}: distance map contains NaN")
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}

    def writer(tmp):
        OpenEXR.File(header, {DISTANCE_CHANNEL: d}).write(tmp)

    _atomic_via(path, writer)


def read_distance_exr(path: Path, channel: str = DISTANCE_CHANNEL) -> np.ndarray:
    """Read a distance EXR -> (H, W) float32 metres.  Values above 1e9 (Cycles' 'no hit') become +inf."""
    path = Path(path)
    if not path.is_file():
        raise FrameError(f"{path}: file is missing")
    try:
        # separate_channels + every part: Blender 5.0 writes multilayer EXRs as multi-part files
        # (Combined in part 0, Depth in part 1), and ``File.channels()`` only sees part 0.
        channels = {}
        for part in OpenEXR.File(str(path), separate_channels=True).parts:
            channels.update(part.channels)
    except Exception as exc:  # OpenEXR raises a bare Exception on corrupt input
        raise FrameError(f"{path}: not a readable OpenEXR file ({exc})") from None
    if channel not in channels:
        raise FrameError(f"{path}: no channel named {channel!r} (found {sorted(channels)})")
    d = np.asarray(channels[channel].pixels, dtype=np.float32)
    if d.ndim != 2:
        raise FrameError(f"{path}: channel {channel!r} must be single-valued, got shape {d.shape}")
    if np.isnan(d).any():
        raise FrameError(f"{path}: channel {channel!r} contains NaN")
    d = np.where(d > NO_HIT_THRESHOLD_M, np.float32(np.inf), d)
    if (d <= 0).any():
        raise FrameError(f"{path}: distances must be positive (found min {float(d.min()):.4g} m)")
    return d


def write_png(path: Path, image: np.ndarray) -> None:
    """Write an (H, W, 3) uint8 RGB image as an 8-bit PNG, atomically."""
    img = np.asarray(image)
    if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] != 3:
        raise FrameError(f"{path}: image must be (H, W, 3) uint8, got {img.shape} {img.dtype}")
    ok, buf = cv2.imencode(".png", cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
    if not ok:
        raise FrameError(f"{path}: PNG encoding failed")
    atomic_write_bytes(path, buf.tobytes())


def read_png(path: Path) -> np.ndarray:
    """Read an 8-bit PNG -> (H, W, 3) uint8 RGB."""
    path = Path(path)
    if not path.is_file():
        raise FrameError(f"{path}: file is missing")
    raw = np.fromfile(str(path), dtype=np.uint8)
    img = cv2.imdecode(raw, cv2.IMREAD_UNCHANGED) if raw.size else None
    if img is None:
        raise FrameError(f"{path}: not a readable image")
    if img.dtype != np.uint8:
        raise FrameError(f"{path}: must be 8-bit, got {img.dtype}")
    if img.ndim == 2:
        img = np.repeat(img[:, :, None], 3, axis=2)
    elif img.shape[2] == 4:
        img = cv2.cvtColor(img, cv2.COLOR_BGRA2RGB)
    elif img.shape[2] == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
    else:
        raise FrameError(f"{path}: unsupported channel count {img.shape[2]}")
    return img


# --------------------------------------------------------------------------------------------- validation


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
    _require(bool(np.allclose(rot.T @ rot, np.eye(3), atol=1e-5)), where, "rotation is not orthonormal")
    _require(abs(np.linalg.det(rot) - 1.0) < 1e-5, where, "rotation is not proper (det != +1)")
    return CameraPose(pos, rot)


def validate_metadata(meta: dict, meta_path: Path) -> None:
    """Check a parsed ``frame.json``; raise :class:`FrameError` naming the file on the first problem."""
    _require(isinstance(meta, dict), meta_path, "must be a JSON object")
    _require(meta.get("format") == FORMAT, meta_path, f"format must be {FORMAT!r}, got {meta.get('format')!r}")
    for key, typ in (("scene", str), ("viewpoint", str), ("width", int), ("height", int),
                     ("baseline_m", (int, float)), ("cameras", dict)):
        _require(key in meta, meta_path, f"missing key {key!r}")
        _require(isinstance(meta[key], typ) and not isinstance(meta[key], bool), meta_path,
                 f"{key!r} has the wrong type ({type(meta[key]).__name__})")
    w, h = meta["width"], meta["height"]
    _require(w > 0 and h > 0, meta_path, f"width and height must be positive, got {w}x{h}")
    _require(w == 2 * h, meta_path, f"equirectangular frames need width == 2*height, got {w}x{h}")
    b = float(meta["baseline_m"])
    _require(np.isfinite(b) and b > 0, meta_path, f"baseline_m must be positive and finite, got {b}")
    for name in CAMERA_NAMES:
        _require(name in meta["cameras"], meta_path, f"cameras.{name} is missing")
    if "renderer" in meta:
        _require(isinstance(meta["renderer"], dict), meta_path, "'renderer' must be an object")


def read_frame(directory: Path, load_distance: bool = True) -> Frame:
    """Read and validate one ``tri360-frame/1`` directory.

    Raises:
        FrameError: naming the offending file, for anything missing or malformed.
    """
    directory = Path(directory)
    meta_path = directory / "frame.json"
    if not meta_path.is_file():
        raise FrameError(f"{meta_path}: file is missing (not a tri360 frame directory)")
    try:
        meta = json.loads(meta_path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise FrameError(f"{meta_path}: not valid JSON ({exc})") from None
    validate_metadata(meta, meta_path)
    cameras = {name: _parse_pose(meta_path, name, meta["cameras"][name]) for name in CAMERA_NAMES}
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
                 renderer=meta.get("renderer", {}), path=directory)


def frame_dir(root: Path, scene: str, viewpoint: str) -> Path:
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

    The frame is built in a hidden sibling directory and renamed into place; an existing frame at the
    target is replaced only after the new one is complete.
    """
    target = frame_dir(root, frame.scene, frame.viewpoint)
    target.parent.mkdir(parents=True, exist_ok=True)
    meta = frame.metadata()
    validate_metadata(meta, target / "frame.json")
    tmp = Path(tempfile.mkdtemp(dir=target.parent, prefix=f".{frame.viewpoint}.partial-"))
    try:
        for name in CAMERA_NAMES:
            img = frame.images[name]
            if img.shape[:2] != (frame.height, frame.width):
                raise FrameError(f"{tmp / (name + '.png')}: image is {img.shape[1]}x{img.shape[0]}, "
                                 f"frame is {frame.width}x{frame.height}")
            write_png(tmp / f"{name}.png", img)
            if name in frame.distance:
                write_distance_exr(tmp / f"{name}.distance.exr", frame.distance[name])
        atomic_write_text(tmp / "frame.json", json.dumps(meta, indent=2) + "\n")
        if target.exists():
            old = target.with_name(f".{frame.viewpoint}.old-{os.getpid()}")
            os.replace(target, old)
            os.replace(tmp, target)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, target)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return target


def find_frames(root: Path) -> list[Path]:
    """All frame directories (those holding ``frame.json``) under ``root``, sorted; hidden dirs skipped."""
    root = Path(root)
    out = []
    for meta in sorted(root.rglob("frame.json")):
        rel = meta.parent.relative_to(root)
        if any(part.startswith(".") for part in rel.parts):
            continue
        out.append(meta.parent)
    return out
