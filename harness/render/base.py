"""What every renderer shares: the settings, the ``Renderer`` interface, sRGB encoding and frame provenance.

A renderer is built once per scene and then renders rig placements::

    with open_renderer("raycast", spec, RenderSettings(width=400)) as renderer:   # harness.render.registry
        frame = renderer.render(rig, scene="synthetic_box", viewpoint="vp000")   # -> harness.data.frame.Frame

Every backend (``cycles``, ``raycast``) subclasses :class:`BaseRenderer`, which owns the loop over the three
cameras, the timing, the progress callback and the one provenance writer (:func:`provenance`), so a frame's
``renderer`` dict has the same layout whichever backend drew it.  A backend supplies only how to draw one
camera (:meth:`BaseRenderer.render_camera`), what it records about itself (:meth:`BaseRenderer.engine`),
which scenes it cannot draw (:meth:`BaseRenderer.unsupported`) and which settings change its pixels
(``pixel_settings``).
"""

from __future__ import annotations

import abc
import platform
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, fields
from typing import ClassVar, Protocol, runtime_checkable

import numpy as np

from harness import __version__
from harness.data.errors import UserError
from harness.data.frame import Frame
from harness.data.jsonio import to_jsonable
from harness.data.provenance import source_commit
from reconstruction.camera.rig import CAMERA_NAMES, CameraPose, Rig
from reconstruction.photometry import linear_to_srgb
from scenes.model import SceneSpec

__all__ = ["RenderSettings", "Renderer", "BaseRenderer", "RenderError", "OnCamera", "srgb_encode", "provenance",
           "identity", "recorded_identity", "scene_label"]

OnCamera = Callable[[str, float], None]
"""Progress callback: ``on_camera(camera_name, seconds)`` after each of C, U, R."""


class RenderError(UserError):
    """A renderer failed in a way the user must look into (e.g. the Cycles worker crashed); names its log."""


@dataclass(frozen=True)
class RenderSettings:
    """Render settings, shared by every backend (each uses the fields it understands).

    Attributes:
        width: panorama width W, pixels (height = W / 2).
        samples: Cycles path-traced samples per pixel (the maximum when adaptive sampling is on).
        adaptive_threshold: Cycles adaptive sampling noise threshold (0 = off: every pixel gets ``samples``).
        adaptive_min_samples: Cycles adaptive sampling minimum samples per pixel (0 = Cycles' automatic choice).
        seed: Cycles sampling seed (noise pattern).  The scene layout and viewpoints have their own seed
            (``SceneSpec.params["seed"]``); ``tri360 render --seed`` sets both.
        threads: CPU threads, 0 = all cores (Cycles).
        denoise: run OpenImageDenoise (CPU) on Cycles' colour; distance is never denoised.
        max_bounces: Cycles total light bounces; diffuse/glossy are capped at this, transmission may go a
            little higher so glass stays clear.
        diffuse_bounces, glossy_bounces: Cycles per-type bounce limits (each also capped at ``max_bounces``).
        filter_width: Cycles pixel filter (Blackman-Harris) width, pixels.
        clamp_indirect: Cycles clamp on indirect sample values (0 = off); suppresses fireflies at low samples.
        light_tree: Cycles' light tree for picking which light(s) to sample: on the 12-light classroom it
            gives the noise of about 1.7x the samples, but each sample costs about 1.8x as much (off by default).
        denoise_prefilter: OIDN guide-pass prefilter, ``"ACCURATE"``, ``"FAST"`` or ``"NONE"``.
        denoise_quality: OIDN quality, ``"HIGH"``, ``"BALANCED"`` or ``"FAST"``.
        supersample: ray-caster colour rays per pixel along each axis (ss x ss, averaged in linear RGB).

    The Cycles defaults are the result of the studies in ``docs/rendering.md`` (1000 x 500 classroom, 2 cores):
    with 20 samples and no light tree, ``tri360 render`` draws the default frame in 58.7-59.8 s (3 renders; the
    earlier 12 samples with the light tree: 62-65 s), and the default method's MAE is the same (0.0862 m over 3
    viewpoints x 2 noise seeds for both).  Fewer samples, OIDN quality BALANCED or 8 samples cost reconstruction
    accuracy on full frames; OIDN prefilter FAST, fewer bounces and albedo-only guides added image noise; adaptive
    sampling stopped no pixel at these sample counts.
    """

    width: int = 1000
    samples: int = 20
    adaptive_threshold: float = 0.0
    adaptive_min_samples: int = 0
    seed: int = 0
    threads: int = 0
    denoise: bool = True
    max_bounces: int = 4
    diffuse_bounces: int = 3
    glossy_bounces: int = 2
    filter_width: float = 1.5
    clamp_indirect: float = 10.0
    light_tree: bool = False
    denoise_prefilter: str = "ACCURATE"
    denoise_quality: str = "HIGH"
    supersample: int = 2

    @property
    def height(self) -> int:
        return self.width // 2

    def check(self) -> None:
        """Raise ValueError naming the first field that no renderer can use."""
        if self.width < 8 or self.width % 2:
            raise ValueError(f"width must be an even number >= 8, got {self.width}")
        for name in ("samples", "supersample"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        if not self.adaptive_threshold >= 0:
            raise ValueError(f"adaptive_threshold must be >= 0 (0 = off), got {self.adaptive_threshold}")
        for name in ("threads", "max_bounces", "diffuse_bounces", "glossy_bounces", "adaptive_min_samples"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")


SETTING_NAMES = tuple(f.name for f in fields(RenderSettings))


# ------------------------------------------------------------------------------------------------ colour


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """Scene-linear RGB (..., 3) -> 8-bit sRGB (..., 3) uint8 (:func:`reconstruction.photometry.linear_to_srgb`:
    clip to [0, 1] (NaN -> 0), IEC 61966-2-1 transfer function, round half up).  For Cycles' Combined pass this
    is Blender's own 'Standard' view transform at exposure 0, gamma 1, no look."""
    return linear_to_srgb(linear)


# -------------------------------------------------------------------------------------------- provenance


def scene_label(spec: SceneSpec) -> str:
    """``family:preset`` of a spec built by the registry (just the family name otherwise)."""
    preset = spec.params.get("preset")
    return f"{spec.name}:{preset}" if preset else spec.name


def identity(renderer: str, pixel_settings: tuple[str, ...], settings: RenderSettings, spec: SceneSpec,
             baseline_m: float) -> dict:
    """Everything that decides a frame's pixels and ground truth, as recorded in (and read back from) frame.json.

    Keys: ``renderer``, ``width``, ``baseline_m``, one per pixel setting of that renderer, ``scene params``
    (including preset and seed) and ``scene code version``.  Two frames with equal identities (and equal
    camera poses) are the same render.
    """
    out = {"renderer": renderer, "width": int(settings.width), "baseline_m": float(baseline_m)}
    out |= {name: getattr(settings, name) for name in pixel_settings if name != "width"}
    out["scene params"] = to_jsonable(spec.params)
    out["scene code version"] = spec.code_version or None
    return out


def recorded_identity(meta: dict) -> dict:
    """The :func:`identity` of a stored frame, from its parsed ``frame.json`` (None for what it lacks)."""
    r = meta.get("renderer") if isinstance(meta.get("renderer"), dict) else {}
    settings = r.get("settings") if isinstance(r.get("settings"), dict) else {}
    scene = r.get("scene") if isinstance(r.get("scene"), dict) else {}
    out = {"renderer": r.get("renderer"), "width": meta.get("width"), "baseline_m": meta.get("baseline_m")}
    for name in r.get("pixel_settings") or ():
        if name != "width":
            out[name] = settings.get(name)
    out["scene params"] = scene.get("params")
    out["scene code version"] = scene.get("code_version")
    return out


def provenance(renderer: str, engine: dict, pixel_settings: tuple[str, ...], settings: RenderSettings,
               spec: SceneSpec, rig: Rig, seconds: dict[str, float]) -> dict:
    """The ``renderer`` dict of ``frame.json``, the same layout for every backend.

    Args:
        renderer: backend name (``"cycles"``, ``"raycast"``).
        engine: what the backend records about itself: ``engine`` (its name), ``versions`` (of the libraries
            it ran on; tri360's version and git commit, Python's and NumPy's are added) and any backend-specific
            detail (bounces, denoiser, shading model...).
        pixel_settings: the settings that change this backend's pixels (compared on a rerun).
        settings: every render setting (all recorded, used or not).
        spec: the scene; its family, preset, parameters and code version are recorded.
        rig: the rig placement.
        seconds: wall time per stage, seconds (``build``, ``C``, ``U``, ``R``, ``total``).
    """
    engine = dict(engine)
    versions = {"tri360": __version__, "commit": source_commit(), "python": platform.python_version(),
                "numpy": np.__version__, **engine.pop("versions", {})}
    return {
        "renderer": renderer,
        "engine": engine.pop("engine", renderer),
        "versions": versions,
        "settings": asdict(settings),
        "pixel_settings": list(pixel_settings),
        "scene": {"family": spec.name, "preset": spec.params.get("preset"), "seed": spec.params.get("seed"),
                  "params": to_jsonable(spec.params), "code_version": spec.code_version or None},
        "rig": {"position": [float(x) for x in rig.position], "yaw_rad": float(rig.yaw_rad),
                "baseline_m": float(rig.baseline_m),
                # a level rig records no tilt, so its frame.json stays byte-identical to before tilt existed
                **({"pitch_rad": float(rig.pitch_rad), "roll_rad": float(rig.roll_rad)} if rig.tilted else {})},
        "seconds": {k: round(float(v), 3) for k, v in seconds.items()},
        "details": to_jsonable(engine),
    }


# ------------------------------------------------------------------------------------------------ renderers


@runtime_checkable
class Renderer(Protocol):
    """What the render job needs from a backend, built once per scene as ``Backend(spec, settings, verbose)``.

    Attributes:
        name: the ``--renderer`` name.
        pixel_settings: :class:`RenderSettings` fields that change this backend's pixels (a rerun into an
            existing data root compares them).
    """

    name: ClassVar[str]
    pixel_settings: ClassVar[tuple[str, ...]]

    def render(self, rig: Rig, scene: str, viewpoint: str, on_camera: OnCamera | None = None) -> Frame:
        """Render C, U and R of ``rig`` -> a complete :class:`Frame` named ``scene``/``viewpoint``."""
        ...

    def close(self) -> None:
        """Release what the constructor acquired (processes, temporary files); idempotent."""
        ...


class BaseRenderer(abc.ABC):
    """Shared part of every backend: refusal of unsupported scenes, the camera loop, timing and provenance.

    Subclasses set ``name``, ``description`` and ``pixel_settings`` and implement :meth:`render_camera` and
    :meth:`engine`; they may override :meth:`unsupported`, :meth:`_build` and :meth:`close`.

    Raises (constructor):
        UserError: the backend cannot draw ``spec`` (naming the scene and the reason).
        ValueError: invalid settings or spec.
    """

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    pixel_settings: ClassVar[tuple[str, ...]] = ("width",)

    def __init__(self, spec: SceneSpec, settings: RenderSettings, verbose: bool = False):
        reason = self.unsupported(spec)
        if reason:
            raise UserError(f"renderer {self.name!r} cannot draw scene {scene_label(spec)!r}: {reason}")
        settings.check()
        spec.validate()
        self.spec, self.settings, self.verbose = spec, settings, verbose
        t0 = time.perf_counter()
        self._build()
        self.build_seconds = time.perf_counter() - t0

    @classmethod
    def unsupported(cls, spec: SceneSpec) -> str | None:
        """Why this backend cannot draw ``spec`` (one short phrase), or None if it can."""
        return None

    def _build(self) -> None:  # noqa: B027 (optional hook)
        """Prepare the scene once (before any render)."""

    @abc.abstractmethod
    def render_camera(self, name: str, pose: CameraPose) -> tuple[np.ndarray, np.ndarray]:
        """One camera -> ((H, W, 3) uint8 sRGB image, (H, W) float32 distance in metres, +inf = no surface)."""

    @abc.abstractmethod
    def engine(self) -> dict:
        """Provenance of the backend: ``{"engine": str, "versions": {...}, ...details}`` (JSON values)."""

    def close(self) -> None:  # noqa: B027 (optional hook)
        """Release resources; idempotent."""

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def render(self, rig: Rig, scene: str, viewpoint: str, on_camera: OnCamera | None = None) -> Frame:
        """Render the rig's three cameras (C, U, R) -> a :class:`Frame` (not yet written to disk).

        Args:
            rig: the rig placement.
            scene, viewpoint: names recorded in the frame (its directory levels).
            on_camera: called as ``on_camera(camera_name, seconds)`` after each camera (progress bars).
        """
        t0 = time.perf_counter()
        poses = rig.poses()
        images, distance, seconds = {}, {}, {"build": self.build_seconds}
        for name in CAMERA_NAMES:
            tc = time.perf_counter()
            images[name], distance[name] = self.render_camera(name, poses[name])
            seconds[name] = time.perf_counter() - tc
            if on_camera is not None:
                on_camera(name, seconds[name])
        seconds["total"] = time.perf_counter() - t0
        s = self.settings
        return Frame(scene=scene, viewpoint=viewpoint, width=s.width, height=s.height,
                     baseline_m=float(rig.baseline_m), cameras=poses, images=images, distance=distance,
                     renderer=provenance(self.name, self.engine(), self.pixel_settings, s, self.spec, rig,
                                         seconds))
