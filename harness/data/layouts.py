"""The dataset layouts that learned 360-degree stereo methods read, and the conversions to and from tri360's frames.

``tri360 export`` writes frames in these layouts, and ``tri360 score --export`` reads a method's predictions back
from them.  Each layout is data (:data:`LAYOUTS`: the files per frame, the camera each holds, the quantity and its
encoding) plus the small functions below; no command logic.  Cameras: C (the reference, whose distance tri360
scores), U = C + b up, R = C + b right.  The layouts assume parallel cameras (checked by :func:`rig_problem`).

Quantities (each an (H, W) float32 map of camera C unless said otherwise):

- ``distance``: the Euclidean distance along the pixel's ray, metres; what these datasets call "depth" for
  equirect images (each peer's own code below treats it as the ray distance).  No surface (+inf) is written as 0.
- ``disparity``: the angular disparity of C's pixel with respect to U, in degrees: the angle at the scene point
  between the rays from C and from U.  With ``alpha`` the angle of C's ray from the direction to U (the zenith in
  a vertical pair) and ``b = |U - C|``: ``d = atan2(b sin(alpha), r - b cos(alpha))`` and back
  ``r = b sin(alpha + d) / sin(d)``.  No surface gives 0, the peers' "invalid".

Layouts, each checked against the peer's own loader (read, not copied):

- ``3d60``: ``Center_Left_Down/<scene>/<viewpoint>_color_0_Left_Down_0.0.png`` (C), ``Right/...Right_0.0.png`` (R),
  ``Up/...Up_0.0.png`` (U), and ``..._depth_0_<Left_Down|Right|Up>_0.0.exr`` (each camera's distance, float32
  EXR, one channel ``Y``: OpenCV's ``imread(path, IMREAD_ANYDEPTH)`` returns it exactly, checked), and a file list
  ``3d60_<split>.txt`` with the six paths per line (``./<scene>/<file>``, colour C R U then depth C R U).  Verified:
  VCL3D/3D60 ``ThreeD60/common.py`` (placements ``left_down``/``right``/``up``, column order, depth read with
  ``IMREAD_ANYDEPTH``; its loader reads only lists whose paths name one of its three source datasets, so it
  reads an export through a rewritten list); Qjizhi/MCPDepth ``dataloader/dataset3D60Loader.py``
  (``Center_Left_Down/``, ``Right/``, ``Up/`` prefixes, list entries with a leading ``./``, depth used as the ray
  distance in its disparity formula, 0 = invalid).
- ``helvipad``: ``<split>/images_bottom/<scene>_IN/<viewpoint>.jpg`` (C; PNG-encoded, lossless, under the ``.jpg``
  name Helvipad's loader opens), ``images_top`` (U), ``depth_maps`` (C's
  distance, 16-bit PNG, metres x 256) and ``disparity_maps`` (C's disparity w.r.t. U, 16-bit PNG, degrees x 2048);
  0 = invalid, and a value above the 16-bit range (distance >= 256 m, disparity >= 32 degrees) is written as 0.
  Verified: vita-epfl/Helvipad ``360_igev_stereo/general/stereo_datasets.py`` (folders, ``/256`` and ``/2048``,
  ``valid = value > 0``, bottom image first, its maps on the bottom image, image names ``.jpg``) and
  ``general/conversion.py`` (the ray distance from the bottom camera, theta from the nadir: its docstring's corrected
  ``B (sin(theta) / tan(d) - cos(theta))``, which the exported disparity follows; the code at commit 284fc1c still
  has ``+ cos(theta)``).  ``_IN`` makes the sequence filter ``IN`` find the rooms.
- ``360sd``: ``<split>/image_up/<id>.png``, ``image_down/<id>.png`` and ``disp_up/<id>.npy`` (float32 degrees,
  0 = invalid).  360SD-Net's disparity lives on the *up* image, whose camera is the one above; tri360 scores C,
  which is below U.  So both images and the map are turned 180 degrees about the forward axis (rows and columns
  reversed, an exact permutation of pixel centres): in the turned frame U is straight below C, ``image_up`` is
  C turned and ``image_down`` U turned.  Verified: albert100121/360SD-Net ``dataloader/filename_loader.py``
  (folders, ``.npy`` named after the image) and ``utils/disp2de.py`` (depth ``b (sin(theta) / tan(d) +
  cos(theta))``, theta from the nadir of the up image, d in degrees: the up camera's ray distance).

- ``deep360``: MODE's stage 1 (stereo matching on Cassini-rectified pairs), two pairs per frame:
  ``ep1_500frames/<split>/rgb/<id>_12_rgb1.png`` (C) and ``_12_rgb2.png`` (R): the pair C-R; ``_13_rgb1.png`` (C)
  and ``_13_rgb3.png`` (U): the pair C-U; ``disp/<id>_12_disp.npz``, ``disp/<id>_13_disp.npz`` (C's disparity in
  Cassini pixels w.r.t. R, U; ``np.savez``, key ``arr_0``) and ``depth/<id>_depth.npz`` (C's distance in the C-R
  pair's Cassini frame).  A Cassini image of an H-row frame is W = 2H rows (angle about the baseline, theta = pi -
  2 pi (i + 0.5) / W) by H columns (phi = pi/2 - pi (j + 0.5) / H from the plane normal to the baseline); the
  bearing is ``(sin phi, cos phi sin theta, cos phi cos theta)``, the partner camera at -x.  Disparity ``d`` px:
  the partner sees the point at ``phi + d pi / H``, distance ``b cos(phi + d pi / H) / sin(d pi / H)``; 0 = no
  surface (far), NaN = no ground truth.  Verified: nju-ee/MODE-2022 ``dataloader/list_file.py`` (folders
  ``ep1..ep6_500frames/<training|validation|testing>/<rgb|disp|depth>``, pairs found by sorting names: left =
  name ``2i``, right ``2i + 1``, disparity ``i``), ``dataloader/deep360_loader.py`` (npz ``arr_0``, resize to 512 x
  1024 with the disparity scaled by the width ratio) and ``save_output_disparity_stage.py`` ``disp2depth`` (the
  Cassini angles, the distance formula, the pair from the disparity file's name).  The images and maps are
  resampled from C's, R's and U's equirect frames (bilinear; nearest where a neighbour has no value), so they are
  not exact: see docs/learned.md.  Stage 2 (fusion) needs four cameras and six pairs: not exported.

Assumed, not verified: that a model trained on upright 360SD images does well on turned ones (the turn is exact
geometry; a model may still prefer upright rooms); the peers' hard-coded sizes (Helvipad's conversion assumes a
960-row sphere, 360SD-Net's ``disp2de`` 1024 x 512): the layouts hold any W x W/2 frame, and angular disparity
does not depend on the size.
"""

from __future__ import annotations

import io
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from harness.data.atomic import atomic_write_bytes
from harness.data.errors import FrameError, UserError
from harness.data.exr import read_exr_channels, write_exr_channels
from harness.data.outputs import EXPORT_FORMAT as MANIFEST_FORMAT
from reconstruction.camera.equirect import bearing_grid, bearing_to_pixel
from reconstruction.camera.image_ops import rotation_angle_deg, vector_angle_deg
from reconstruction.camera.resample import sample_equirect

__all__ = ["LAYOUTS", "Layout", "MapFile", "Encoding", "ENCODINGS", "MANIFEST", "MANIFEST_FORMAT", "PARALLEL_TOL_DEG",
           "zenith_angle", "disparity_from_distance", "distance_from_disparity", "rig_problem", "frame_paths",
           "read_map", "prediction_candidates", "turn", "to_layout", "from_layout", "RectifiedImage",
           "CASSINI_FROM_CAMERA", "cassini_bearings", "to_cassini", "from_cassini", "to_rectified", "from_rectified"]

MANIFEST = "manifest.json"
PARALLEL_TOL_DEG = 0.1
"""How far (degrees) U - C may be from C's up axis, R - C from its right axis, and U's or R's orientation from C's."""


# ------------------------------------------------------------------------------------------------ geometry


def zenith_angle(height: int) -> np.ndarray:
    """(H, 1) float64 radians: each row's angle from the camera's up axis, ``pi (v + 0.5) / H``."""
    return (math.pi * (np.arange(height, dtype=np.float64) + 0.5) / height)[:, None]


def disparity_from_distance(distance: np.ndarray, alpha: np.ndarray, baseline_m: float) -> np.ndarray:
    """Angular disparity, degrees (H, W) float32, of a reference camera's ray distance ``distance`` (H, W) metres
    with respect to a second camera ``baseline_m`` away; ``alpha`` (H, 1) or (H, W): each ray's angle (radians)
    from the direction to that camera.  No surface (+inf), NaN or a distance <= 0 give 0 (invalid)."""
    r = np.asarray(distance, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        good = np.isfinite(r) & (r > 0)
        d = np.degrees(np.arctan2(baseline_m * np.sin(alpha), np.where(good, r, 1.0) - baseline_m * np.cos(alpha)))
    return np.where(good, d, 0.0).astype(np.float32)


def distance_from_disparity(disparity_deg: np.ndarray, alpha: np.ndarray, baseline_m: float) -> np.ndarray:
    """Back from :func:`disparity_from_distance`: (H, W) float32 metres; a disparity <= 0, >= 180 or not finite
    gives NaN (no prediction)."""
    d = np.radians(np.asarray(disparity_deg, dtype=np.float64))
    with np.errstate(invalid="ignore", divide="ignore"):
        good = np.isfinite(d) & (d > 0) & (d < math.pi)
        r = baseline_m * np.sin(alpha + d) / np.sin(np.where(good, d, 1.0))
    return np.where(good & (r > 0), r, np.nan).astype(np.float32)


CASSINI_FROM_CAMERA = {
    "R": np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]]),
    "U": np.array([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]]),
}
"""Partner -> (3, 3) camera-from-Cassini rotation of C's pair with that partner (columns: the Cassini x, y, z axes in
C's camera frame, X right, Y forward, Z up).  The partner is at -x (MODE's ``disp2depth``), z is forward; C-R:
x left, y up; C-U: x down, y left."""


def cassini_bearings(width: int) -> tuple[np.ndarray, np.ndarray]:
    """The Cassini grid of a W x W/2 equirect frame: W rows, W/2 columns.  -> (bearings (W, W/2, 3) in the Cassini
    frame, phi (1, W/2) radians: each column's angle from the plane normal to the baseline, + toward x)."""
    h = width // 2
    theta = (math.pi - 2.0 * math.pi * (np.arange(width, dtype=np.float64) + 0.5) / width)[:, None]
    phi = (0.5 * math.pi - math.pi * (np.arange(h, dtype=np.float64) + 0.5) / h)[None, :]
    return np.stack(np.broadcast_arrays(np.sin(phi), np.cos(phi) * np.sin(theta), np.cos(phi) * np.cos(theta)),
                    axis=-1), phi


def _sample(image: np.ndarray, u: np.ndarray, v: np.ndarray, values: bool) -> np.ndarray:
    """Bilinear samples of an equirect-like ``image`` (columns wrap, rows clamp); for ``values`` (a float map with
    inf/NaN), nearest where a bilinear neighbour is not finite."""
    if not values:
        return sample_equirect(image, u, v, cv2.INTER_LINEAR)
    lin = sample_equirect(image.astype(np.float32), u, v, cv2.INTER_LINEAR)
    near = sample_equirect(image.astype(np.float32), u, v, cv2.INTER_NEAREST)
    return np.where(np.isfinite(lin), lin, near).astype(np.float32)


def to_cassini(image: np.ndarray, partner: str, values: bool = False) -> np.ndarray:
    """An equirect image or map (H, W[, C]) of C (or of a camera parallel to it) -> the Cassini image (W, H[, C])
    of C's pair with ``partner`` (:data:`CASSINI_FROM_CAMERA`), same dtype; ``values``: a float map (metres)."""
    h, w = image.shape[:2]
    b, _ = cassini_bearings(w)
    u, v = bearing_to_pixel(b @ CASSINI_FROM_CAMERA[partner].T, w, h)
    return _sample(image, u, v, values)


def from_cassini(values: np.ndarray, partner: str) -> np.ndarray:
    """Back from :func:`to_cassini`: a float map (W, H) in the pair's Cassini frame -> C's equirect map (H, W)
    float32 (bilinear, nearest where a neighbour is not finite).  The Cassini map transposed is equirect-like
    (rows: phi, columns: theta, wrapping), so it is sampled as one."""
    w, h = values.shape
    b = bearing_grid(w, h) @ CASSINI_FROM_CAMERA[partner]  # C's bearings in the Cassini frame
    phi = np.arcsin(np.clip(b[..., 0], -1.0, 1.0))
    theta = np.arctan2(b[..., 1], b[..., 2])
    col = (0.5 * math.pi - phi) * h / math.pi - 0.5
    row = (math.pi - theta) * w / (2.0 * math.pi) - 0.5
    return _sample(np.ascontiguousarray(np.asarray(values, dtype=np.float32).T), row, col, True)


def to_rectified(quantity: str, distance: np.ndarray, partner: str, baseline_m: float) -> np.ndarray:
    """C's distance (H, W) metres -> the pair's Cassini map (W, H) float32 of ``quantity``: ``distance`` (metres,
    no surface 0) or ``disparity_px`` (Cassini pixels w.r.t. ``partner``, ``baseline_m`` away; no surface 0).
    NaN (no ground truth) stays NaN (MODE's training mask drops NaN and keeps 0 as far)."""
    r = to_cassini(np.asarray(distance, dtype=np.float32), partner, values=True)
    nan = np.isnan(r)
    if quantity == "distance":
        out = np.where(np.isfinite(r) & (r > 0), r, 0.0)
    else:
        _, phi = cassini_bearings(distance.shape[1])
        out = disparity_from_distance(r, 0.5 * math.pi + phi, baseline_m) * (r.shape[1] / 180.0)
    return np.where(nan, np.nan, out).astype(np.float32)


def from_rectified(quantity: str, values: np.ndarray, partner: str, baseline_m: float) -> np.ndarray:
    """Back from :func:`to_rectified`: a Cassini map (W, H) -> C's distance (H, W) float32 metres, NaN where
    invalid (<= 0, not finite)."""
    v = np.asarray(values, dtype=np.float32)
    if quantity == "distance":
        with np.errstate(invalid="ignore"):
            r = np.where(np.isfinite(v) & (v > 0), v, np.nan).astype(np.float32)
    else:
        _, phi = cassini_bearings(v.shape[0])
        r = distance_from_disparity(v * (180.0 / v.shape[1]), 0.5 * math.pi + phi, baseline_m)
    return from_cassini(r, partner)


# ------------------------------------------------------------------------------------------------ encodings


@dataclass(frozen=True)
class Encoding:
    """How a map is stored: file suffix, a writer ``(path, (H, W) float32 in layout units)`` and a reader
    ``path -> (H, W) float32`` in layout units (0 = invalid as the peers have it)."""

    suffix: str
    write: Callable[[Path, np.ndarray], None]
    read: Callable[[Path], np.ndarray]


def _write_exr(path: Path, values: np.ndarray) -> None:
    write_exr_channels(path, {"Y": np.ascontiguousarray(values, dtype=np.float32)})


def _read_exr(path: Path) -> np.ndarray:
    channels = read_exr_channels(path)
    name = next((c for c in ("Y", "R", "distance", "depth") if c in channels), None)
    if name is None and len(channels) == 1:
        name = next(iter(channels))
    if name is None or channels[name].dtype.kind != "f":
        raise FrameError(f"{path}: expected one float channel (Y, R, distance or depth), found {sorted(channels)}")
    return channels[name].astype(np.float32)


def _write_npy(path: Path, values: np.ndarray) -> None:
    buf = io.BytesIO()
    np.save(buf, np.ascontiguousarray(values, dtype=np.float32), allow_pickle=False)
    atomic_write_bytes(path, buf.getvalue())


def _read_npy(path: Path) -> np.ndarray:
    try:
        a = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise FrameError(f"{path}: not a readable .npy array ({exc})") from None
    a = np.squeeze(np.asarray(a))
    if a.ndim != 2 or a.dtype.kind not in "fiu":
        raise FrameError(f"{path}: expected a numeric (H, W) array, got shape {a.shape} {a.dtype}")
    return a.astype(np.float32)


def _write_npz(path: Path, values: np.ndarray) -> None:
    buf = io.BytesIO()
    np.savez(buf, np.ascontiguousarray(values, dtype=np.float32))  # key arr_0, as MODE's loader reads it
    atomic_write_bytes(path, buf.getvalue())


def _read_npz(path: Path) -> np.ndarray:
    try:
        with np.load(path, allow_pickle=False) as z:
            a = z["arr_0"] if "arr_0" in z.files else z[z.files[0]]
    except (OSError, ValueError, IndexError, KeyError) as exc:
        raise FrameError(f"{path}: not a readable .npz array ({exc})") from None
    a = np.squeeze(np.asarray(a))
    if a.ndim != 2 or a.dtype.kind not in "fiu":
        raise FrameError(f"{path}: expected a numeric (H, W) array, got shape {a.shape} {a.dtype}")
    return a.astype(np.float32)


def _png16(scale: float) -> Encoding:
    """A 16-bit grey PNG holding ``round(value * scale)``; 0 and values beyond 65535 / scale are invalid (0)."""

    def write(path: Path, values: np.ndarray) -> None:
        v = np.asarray(values, dtype=np.float64) * scale
        with np.errstate(invalid="ignore"):
            ok = np.isfinite(v) & (v > 0) & (np.round(v) <= 65535)
        done, buf = cv2.imencode(".png", np.where(ok, np.round(np.where(ok, v, 0)), 0).astype(np.uint16))
        if not done:
            raise FrameError(f"{path}: PNG encoding failed")
        atomic_write_bytes(path, buf.tobytes())

    def read(path: Path) -> np.ndarray:
        raw = cv2.imread(str(path), cv2.IMREAD_ANYDEPTH) if path.is_file() else None
        if raw is None or raw.ndim != 2:
            raise FrameError(f"{path}: not a readable single-channel PNG")
        return (raw.astype(np.float64) / scale).astype(np.float32)

    return Encoding(".png", write, read)


ENCODINGS = {"exr": Encoding(".exr", _write_exr, _read_exr), "npy": Encoding(".npy", _write_npy, _read_npy),
             "npz": Encoding(".npz", _write_npz, _read_npz),
             "png-m256": _png16(256.0), "png-deg2048": _png16(2048.0)}
"""Encoding name -> :class:`Encoding`."""
_RAW = {".npy": ENCODINGS["npy"], ".exr": ENCODINGS["exr"]}
"""What a method may write in place of an exported map, besides the map's own encoding (layout units, float)."""


# -------------------------------------------------------------------------------------------------- layouts


@dataclass(frozen=True)
class MapFile:
    """One exported map: ``camera``'s ``quantity`` (``distance``, ``disparity`` or, with ``partner``,
    ``disparity_px``), at ``path`` (a template with ``{split}``, ``{scene}``, ``{viewpoint}``, ``{id}``, no suffix) in
    ``encoding`` (:data:`ENCODINGS`).  ``partner``: the map is in the Cassini frame of C's pair with that camera
    (:func:`to_rectified`), W rows x H columns; None: C's equirect frame."""

    camera: str
    quantity: str
    path: str
    encoding: str
    partner: str | None = None


@dataclass(frozen=True)
class RectifiedImage:
    """One Cassini-rectified image (:func:`to_cassini`): ``camera``'s image in the frame of C's pair with
    ``partner``, at ``path`` (a template, ``.png``)."""

    camera: str
    partner: str
    path: str


@dataclass(frozen=True)
class Layout:
    """A peer's dataset layout.

    Attributes:
        name, peer: the ``--format`` value and whose loader reads it.
        images: camera name -> path template (``.png``).
        maps: the exported maps; those of camera C are where predictions are read back from.
        cameras: the cameras the layout uses (their rig is checked: :func:`rig_problem`).
        turned: every image and map is turned 180 degrees about the forward axis (rows and columns reversed).
        splits: tri360 split (None: no suite) -> the ``{split}`` folder name.
        file_list: template of a list file with one line per frame (``line``), or None.
        line: template of that line.
        rectified: Cassini-rectified images (written besides ``images``).
        folders: folder templates (``{split}``) created even when empty (the peer lists them).
    """

    name: str
    peer: str
    images: dict[str, str]
    maps: tuple[MapFile, ...]
    cameras: tuple[str, ...]
    turned: bool = False
    splits: tuple[tuple[str | None, str], ...] = ((None, "test"), ("dev", "val"), ("test", "test"),
                                                  ("train", "train"))
    file_list: str | None = None
    line: str = ""
    rectified: tuple[RectifiedImage, ...] = ()
    folders: tuple[str, ...] = ()

    def split_dir(self, split: str | None) -> str:
        return dict(self.splits)[split]


_3D60_NAME = "{viewpoint}_{kind}_0_{place}_0.0"
_3D60_PLACES = {"C": ("Center_Left_Down", "Left_Down"), "R": ("Right", "Right"), "U": ("Up", "Up")}


def _3d60(kind: str, camera: str) -> str:
    folder, place = _3D60_PLACES[camera]
    return f"{folder}/{{scene}}/" + _3D60_NAME.replace("{kind}", kind).replace("{place}", place)


_DEEP360 = "ep1_500frames/{split}/"

LAYOUTS = {
    "3d60": Layout(
        "3d60", "3D60 (VCL3D/3D60 ThreeD60 loaders; MODE, MCPDepth)",
        images={c: _3d60("color", c) + ".png" for c in ("C", "R", "U")},
        maps=tuple(MapFile(c, "distance", _3d60("depth", c), "exr") for c in ("C", "R", "U")),
        cameras=("C", "U", "R"), file_list="3d60_{split}.txt",
        line=" ".join([f"./{{scene}}/{_3D60_NAME.format(viewpoint='{viewpoint}', kind=k, place=_3D60_PLACES[c][1])}"
                       f"{s}" for k, s in (("color", ".png"), ("depth", ".exr")) for c in ("C", "R", "U")])),
    "helvipad": Layout(
        "helvipad", "Helvipad (vita-epfl/Helvipad 360-IGEV-Stereo StereoDataset)",
        # Helvipad's loader opens <viewpoint>.jpg (it derives the image names from the maps' .png names); the images
        # are written losslessly, PNG-encoded under that name (PIL and OpenCV read by content, not by name)
        images={"C": "{split}/images_bottom/{scene}_IN/{viewpoint}.jpg",
                "U": "{split}/images_top/{scene}_IN/{viewpoint}.jpg"},
        maps=(MapFile("C", "distance", "{split}/depth_maps/{scene}_IN/{viewpoint}", "png-m256"),
              MapFile("C", "disparity", "{split}/disparity_maps/{scene}_IN/{viewpoint}", "png-deg2048")),
        cameras=("C", "U")),
    "360sd": Layout(
        "360sd", "360SD-Net (albert100121/360SD-Net filename_loader)",
        images={"C": "{split}/image_up/{id}.png", "U": "{split}/image_down/{id}.png"},
        maps=(MapFile("C", "disparity", "{split}/disp_up/{id}", "npy"),),
        cameras=("C", "U"), turned=True),
    "deep360": Layout(
        "deep360", "Deep360 stage 1, two pairs (nju-ee/MODE-2022 list_deep360_disparity_*, Deep360DatasetDisparity)",
        images={},
        rectified=(RectifiedImage("C", "R", _DEEP360 + "rgb/{id}_12_rgb1.png"),
                   RectifiedImage("R", "R", _DEEP360 + "rgb/{id}_12_rgb2.png"),
                   RectifiedImage("C", "U", _DEEP360 + "rgb/{id}_13_rgb1.png"),
                   RectifiedImage("U", "U", _DEEP360 + "rgb/{id}_13_rgb3.png")),
        maps=(MapFile("C", "disparity_px", _DEEP360 + "disp/{id}_12_disp", "npz", "R"),
              MapFile("C", "disparity_px", _DEEP360 + "disp/{id}_13_disp", "npz", "U"),
              MapFile("C", "distance", _DEEP360 + "depth/{id}_depth", "npz", "R")),
        cameras=("C", "U", "R"),
        splits=((None, "testing"), ("dev", "validation"), ("test", "testing"), ("train", "training")),
        # MODE's lists open every episode's training, validation and testing folders (os.listdir)
        folders=tuple(f"ep{e}_500frames/{s}/{k}" for e in range(1, 7) for s in ("training", "validation", "testing")
                      for k in ("rgb", "disp", "depth"))),
}
"""``--format`` name -> :class:`Layout`."""


def frame_paths(layout: Layout, split: str | None, scene: str, viewpoint: str, index: int) -> dict[str, str]:
    """The fields of the path templates for one frame: ``split``, ``scene``, ``viewpoint`` and ``id``
    (``<index:05d>_<scene>_<viewpoint>``, unique in a flat folder)."""
    return {"split": layout.split_dir(split), "scene": scene, "viewpoint": viewpoint,
            "id": f"{index:05d}_{scene}_{viewpoint}"}


def rig_problem(layout: Layout, cameras: dict, tol_deg: float = PARALLEL_TOL_DEG) -> str | None:
    """Why ``cameras`` (name -> ``CameraPose``) cannot be written in ``layout``, or None: U not straight above C
    along C's up axis, R not straight right of C along its right axis (for layouts that use R), or U's or R's
    orientation not C's, each within ``tol_deg`` degrees."""
    c = cameras["C"]
    axes = {"U": (2, "above"), "R": (0, "right of")}
    for name in layout.cameras:
        if name == "C":
            continue
        axis, where = axes[name]
        off = vector_angle_deg(cameras[name].position - c.position, c.rotation[:, axis])
        if off > tol_deg:
            return f"{name} is not straight {where} C ({off:.3g} degrees off C's axis, tolerance {tol_deg:g})"
        turned = rotation_angle_deg(cameras[name].rotation, c.rotation)
        if turned > tol_deg:
            return (f"{name} is turned {turned:.3g} degrees from C (the layout assumes parallel cameras, tolerance "
                    f"{tol_deg:g})")
    return None


def turn(a: np.ndarray, turned: bool) -> np.ndarray:
    """``a`` (H, W, ...) turned 180 degrees about the forward axis (rows and columns reversed) if ``turned``."""
    return np.ascontiguousarray(a[::-1, ::-1]) if turned else a


def to_layout(quantity: str, distance: np.ndarray, baseline_u: float) -> np.ndarray:
    """C's (or any camera's) distance (H, W) metres -> the layout's map of ``quantity`` (0 = invalid)."""
    if quantity == "distance":
        d = np.asarray(distance, dtype=np.float32)
        return np.where(np.isfinite(d) & (d > 0), d, 0).astype(np.float32)
    return disparity_from_distance(distance, zenith_angle(distance.shape[0]), baseline_u)


def from_layout(quantity: str, values: np.ndarray, baseline_u: float) -> np.ndarray:
    """A layout's map of ``quantity`` -> distance (H, W) float32 metres, NaN where invalid (<= 0, not finite)."""
    if quantity == "distance":
        v = np.asarray(values, dtype=np.float32)
        with np.errstate(invalid="ignore"):
            return np.where(np.isfinite(v) & (v > 0), v, np.nan).astype(np.float32)
    return distance_from_disparity(values, zenith_angle(values.shape[0]), baseline_u)


def prediction_candidates(layout: Layout, fields: dict[str, str]) -> list[tuple[str, MapFile, Encoding]]:
    """Where a method's prediction for one frame may be, in order: for each map of C, its own encoding, then
    ``.npy`` and ``.exr`` (float, layout units).  -> ``[(relative path, map, encoding)]``."""
    out = []
    for m in layout.maps:
        if m.camera != "C":
            continue
        base = m.path.format(**fields)
        own = ENCODINGS[m.encoding]
        for enc in (own, *(e for s, e in _RAW.items() if s != own.suffix)):
            out.append((base + enc.suffix, m, enc))
    return out


def read_map(path: Path, encoding: Encoding, width: int, height: int) -> np.ndarray:
    """One map in layout units -> (H, W) float32.

    Raises:
        UserError: naming ``path``: unreadable, or not ``width`` x ``height``.
    """
    values = encoding.read(path)
    if values.shape != (height, width):
        raise UserError(f"{path}: size {values.shape[1]}x{values.shape[0]} != the frame's {width}x{height}")
    return values
