"""The predictions format ``tri360-pred/1``: what any method, ours or anyone's, hands to ``tri360 score``.

::

    <pred_root>/<scene>/<viewpoint>/
      distance.exr      # float32 (float16 accepted), one channel "distance", metres, camera C's distance,
                        # frame size; NaN, +inf or 0 = no prediction at that pixel (scored with error = true
                        # distance); a negative value, -inf included, is refused
      confidence.exr    # optional, float32 (or float16), one channel "confidence", higher = more confident
    <pred_root>/method.json   # optional: {"name", "description", "url", "parameters"}

Readers validate and raise :class:`FrameError` naming the file: a missing frame, a wrong channel name, a channel
that is not floating point (float32 or float16: a uint32 channel is not metres), a size other than the frame's, a
map with no valid prediction at all, a negative distance, ``-inf`` included (a sign error: a distance is never
negative; write NaN, +inf or 0 for "no prediction"), a NaN confidence where the distance is valid.  The method's
name (method.json's ``name``) is an outside name: ``tri360 score`` checks it before it becomes part of a path
(:func:`harness.data.names.check_name`).  Writers are atomic.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from harness.data import jsonio
from harness.data.atomic import atomic_write_text
from harness.data.errors import FrameError
from harness.data.exr import CONFIDENCE_CHANNEL, DISTANCE_CHANNEL, float_channel, read_exr_channels, write_float_map
from reconstruction.methods.base import MethodOutput

__all__ = ["FORMAT", "Prediction", "PredictionMethod", "prediction_dir", "write_prediction", "read_prediction",
           "read_method_info", "write_method_info", "METHOD_INFO_KEYS"]

FORMAT = "tri360-pred/1"
METHOD_INFO_KEYS = ("name", "description", "url", "parameters")


@dataclass
class Prediction:
    """One frame's prediction.

    Attributes:
        distance: (H, W) float32 metres; NaN, +inf or 0 = no prediction (never negative, never -inf).
        confidence: (H, W) float32 (higher = more confident) or None.
        path: the directory it was read from.
    """

    distance: np.ndarray
    confidence: np.ndarray | None = None
    path: Path | None = None
    info: dict = field(default_factory=dict)


def prediction_dir(pred_root: Path, scene: str, viewpoint: str) -> Path:
    return Path(pred_root) / scene / viewpoint


def write_prediction(pred_root: Path, scene: str, viewpoint: str, distance: np.ndarray,
                     confidence: np.ndarray | None = None) -> Path:
    """Write one frame's prediction (each file atomically); returns its directory."""
    d = prediction_dir(pred_root, scene, viewpoint)
    write_float_map(d / "distance.exr", np.asarray(distance, np.float32), DISTANCE_CHANNEL)
    if confidence is not None:
        write_float_map(d / "confidence.exr", np.asarray(confidence, np.float32), CONFIDENCE_CHANNEL)
    return d


def _one_channel(path: Path, want: str) -> np.ndarray:
    channels = read_exr_channels(path)
    if want not in channels:
        raise FrameError(f"{path}: no channel named {want!r} (found {', '.join(sorted(channels)) or 'none'}); "
                         f"{FORMAT} wants exactly one float channel {want!r}")
    if channels[want].dtype.kind != "f":
        raise FrameError(f"{path}: channel {want!r} holds {channels[want].dtype} values; {FORMAT} wants float32 "
                         "(or float16)")
    return float_channel(channels, path, want)


def read_prediction(pred_root: Path, scene: str, viewpoint: str, width: int, height: int) -> Prediction:
    """Read and validate one frame's prediction against the frame's size.

    Raises:
        FrameError: naming the file, for anything missing or malformed (see the module doc).
    """
    d = prediction_dir(pred_root, scene, viewpoint)
    path = d / "distance.exr"
    if not path.is_file():
        raise FrameError(f"{path}: file is missing (no prediction for frame {scene}/{viewpoint} under {pred_root})")
    dist = _one_channel(path, DISTANCE_CHANNEL)
    if dist.shape != (height, width):
        raise FrameError(f"{path}: size {dist.shape[1]}x{dist.shape[0]} != the frame's {width}x{height}")
    with np.errstate(invalid="ignore"):
        negative = dist < 0  # -inf included; NaN compares False
        valid = np.isfinite(dist) & (dist > 0)
    if negative.any():
        raise FrameError(f"{path}: {int(negative.sum())} pixels have a negative distance (min "
                         f"{float(dist[negative].min()):.4g} m); write NaN, +inf or 0 where there is no prediction")
    if not valid.any():
        raise FrameError(f"{path}: no pixel holds a valid prediction (all NaN, inf or 0)")
    conf = None
    cpath = d / "confidence.exr"
    if cpath.exists():
        conf = _one_channel(cpath, CONFIDENCE_CHANNEL)
        if conf.shape != dist.shape:
            raise FrameError(f"{cpath}: size {conf.shape[1]}x{conf.shape[0]} != the frame's {width}x{height}")
        if np.isnan(conf[valid]).any():
            raise FrameError(f"{cpath}: confidence is NaN at {int(np.isnan(conf[valid]).sum())} pixels that have a "
                             "valid distance")
    return Prediction(dist, conf, d)


def read_method_info(pred_root: Path) -> dict:
    """``<pred_root>/method.json`` (optional) -> dict with the keys of :data:`METHOD_INFO_KEYS` it has.

    Raises:
        FrameError: the file exists but is not a JSON object, or a known key has the wrong type.
    """
    path = Path(pred_root) / "method.json"
    if not path.exists():
        return {}
    try:
        raw = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise FrameError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(raw, dict):
        raise FrameError(f"{path}: must be a JSON object with keys {', '.join(METHOD_INFO_KEYS)}")
    for key in ("name", "description", "url"):
        if key in raw and not isinstance(raw[key], str):
            raise FrameError(f"{path}: {key!r} must be a string")
    if "parameters" in raw and not isinstance(raw["parameters"], dict):
        raise FrameError(f"{path}: 'parameters' must be an object")
    return raw


def write_method_info(pred_root: Path, info: dict) -> Path:
    """Write ``<pred_root>/method.json`` atomically (strict JSON)."""
    path = Path(pred_root) / "method.json"
    atomic_write_text(path, jsonio.dumps({"format": FORMAT, **info}, indent=2))
    return path


@dataclass(frozen=True)
class PredictionMethod:
    """A method whose outputs are predictions on disk (``tri360 score``): it reads the frame's maps, so it is handed
    the frame's names (the runtime's ``run_blind``), never its ground truth.

    Attributes:
        label: the name the results use (``--method``, else method.json's ``name``, else the folder's name), a
            safe name (:func:`harness.data.names.check_name`): it becomes part of the maps' paths.
        root: the predictions root.
        info: the contents of ``method.json`` (may be empty).
        label_source: where the label came from (``--method``, the method.json path, the folder), for messages.
    """

    label: str
    root: Path
    info: dict = field(default_factory=dict)
    label_source: str = "--method"

    def config(self) -> dict:
        return {"kind": "predictions", "format": FORMAT, "label": self.label, "label_source": self.label_source,
                "root": str(self.root.resolve()), "method.json": self.info}

    def run(self, frame) -> MethodOutput:
        pred = read_prediction(self.root, frame.scene, frame.viewpoint, frame.width, frame.height)
        return MethodOutput(distance=pred.distance, confidence=pred.confidence, seconds={"total": float("nan")})
