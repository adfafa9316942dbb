"""The ``captured`` condition: a frame's twin as a real rig would have recorded it.

From an ideal frame (rendered with identical, perfectly exposed cameras), :func:`captured_twin` derives the same
scene and viewpoint seen through three cameras that each meter their own exposure and white balance, whose lenses
darken towards their edges, whose sensors add noise and whose encoders compress (each camera's
:class:`harness.data.photometric.Photometric`, drawn from a :class:`harness.data.photometric.CameraDistribution`),
and whose calibration is slightly off (U's and R's told orientation and position; C's is exact, so C's ground
truth stays exact).  No second render: the ideal images are transformed in linear light
(:func:`harness.render.camera.apply`).

The twin records each camera's ``photometric`` in ``frame.json`` and, in ``renderer.condition``, the condition's
name, the distribution (:meth:`CameraDistribution.to_json`: a ``tri360-v2`` condition's record is what it always
was), the seed, the calibration error drawn, the true poses of U and R (``true_cameras``, ``true_baseline_m``: U's
and R's distance maps are those of their true poses) and its source frame (``source``: its path and the SHA-256 over
its files, :func:`harness.commands.perturb.source_record`, as ``tri360 perturb`` records).  Deterministic: the same
frame, distribution, seed and source record give byte-identical twins, and :func:`calibration_error` redraws the
told poses from the true ones without the images.
"""

from __future__ import annotations

import zlib

import numpy as np

from harness.commands.parts import perturbations as P
from harness.data.frame import Frame
from harness.data.photometric import CameraDistribution
from harness.render.camera import apply
from reconstruction.camera.rig import CAMERA_NAMES, CameraPose

__all__ = ["CONDITIONS", "captured_twin", "calibration_error", "twin_generator"]

CONDITIONS = ("ideal", "captured")
"""The conditions of ``tri360-v2``'s splits: the rendered frames and their captured twins (a suite may declare more,
``tri360-v3``: each is a :class:`CameraDistribution` and its twins are derived here alike)."""


def twin_generator(seed: int, part: str, camera: str) -> np.random.Generator:
    """The random stream of one part (``"photometric"``, ``"rotation"``, ``"translation"``) of one camera."""
    return np.random.default_rng([int(seed), zlib.crc32(b"captured"), zlib.crc32(part.encode()),
                                  zlib.crc32(camera.encode())])


def calibration_error(cameras: dict[str, CameraPose], dist: CameraDistribution,
                      seed: int) -> tuple[dict[str, CameraPose], dict]:
    """The told poses of a twin whose true poses are ``cameras`` and the calibration error drawn for ``seed``.

    U's and R's told orientation is turned by an angle uniform in ``dist.rotation_deg`` about a random world axis,
    then their told position moved by a length uniform in ``dist.translation_mm`` in a random world direction
    (each camera and part its own stream, :func:`twin_generator`); C's is exact.

    Returns:
        ``(told cameras, drawn)``, ``drawn`` = ``{camera: {"rotation": {...}, "translation": {...}}}`` with only
        the non-zero parts (``renderer.condition.calibration_error``).
    """
    told = dict(cameras)
    drawn: dict = {}
    for k in ("U", "R"):
        rng = twin_generator(seed, "rotation", k)
        deg = float(rng.uniform(*dist.rotation_deg))
        if deg > 0:
            told[k], drawn.setdefault(k, {})["rotation"] = P.perturb_pose_rotation(told[k], deg, rng)
        rng = twin_generator(seed, "translation", k)
        mm = float(rng.uniform(*dist.translation_mm))
        if mm > 0:
            told[k], drawn.setdefault(k, {})["translation"] = P.perturb_pose_translation(told[k], mm, rng)
    return told, drawn


def captured_twin(frame: Frame, dist: CameraDistribution, seed: int, name: str = "captured",
                  source: dict | None = None) -> Frame:
    """``frame`` as a real rig would have recorded it (module doc); ``frame`` is unchanged.

    Args:
        frame: an ideal frame (no camera carries a photometric record, its told poses are its true ones).
        dist: the distribution the cameras are drawn from.
        seed: the twin's seed (each camera and part has its own stream, :func:`twin_generator`).
        name: the condition's name, recorded in ``renderer.condition``.
        source: what the record says of the source frame (``path``, ``sha256``); None records none.
    Raises:
        ValueError: ``frame`` is already a captured frame (its cameras carry photometric records) or records true
            poses other than its told ones (a twin or a frame perturbed with calibration error).
    """
    if frame.photometric:
        raise ValueError(f"{frame.scene}/{frame.viewpoint} already records its cameras' photometry: derive the "
                         "captured twin from the ideal frame")
    if any(isinstance(frame.renderer.get(r), dict) and "true_cameras" in frame.renderer[r]
           for r in ("condition", "perturbation")):
        raise ValueError(f"{frame.scene}/{frame.viewpoint} records true poses other than its told ones: derive the "
                         "captured twin from the ideal frame")
    photometric = {k: dist.draw(twin_generator(seed, "photometric", k)) for k in CAMERA_NAMES}
    images = {k: apply(frame.images[k], photometric[k]) for k in CAMERA_NAMES}
    cameras, drawn = calibration_error(dict(frame.cameras), dist, seed)
    told = [float(np.linalg.norm(cameras[k].position - cameras["C"].position)) for k in ("U", "R")]
    baseline = float(np.mean(told))
    record = {"name": name, "seed": int(seed), "distribution": dist.to_json(), "calibration_error": drawn,
              "true_cameras": {k: frame.cameras[k].to_json() for k in ("U", "R")},
              "true_baseline_m": float(frame.baseline_m)}
    if source is not None:
        record["source"] = dict(source)
    renderer = {**frame.renderer, "condition": record}
    return Frame(scene=frame.scene, viewpoint=frame.viewpoint, width=frame.width, height=frame.height,
                 baseline_m=baseline, cameras=cameras, images=images, distance=dict(frame.distance),
                 renderer=renderer, photometric=photometric)
