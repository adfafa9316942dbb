"""The photometric record of one camera in ``frame.json`` (``cameras.<name>.photometric``).

A camera without one is ideal: its PNG is the scene-linear light encoded as sRGB.  A real camera meters its own
exposure and white balance, its lenses darken towards their edges, its sensor adds noise, its response curve and
encoder shape the bytes; :class:`Photometric` records each of these, and ``harness.render.camera.apply`` turns an
ideal image into that camera's image, in linear light, in this order: vignetting (gain
``1 - edge_loss * (theta / 90 deg) ** 2``, ``theta`` the angle from the nearer of the two back-to-back lens axes
``+-axis``), exposure (``2 ** exposure_stops``), white balance (R, G, B gains), noise (variance
``shot * x + read`` at linear level ``x``, seeded with ``seed``), the response curve (``"srgb"`` or ``"gamma-G"``),
JPEG at ``jpeg_quality`` (0 = none).  A record in a file has every key of :data:`KEYS` (none takes a default).

Three optional keys (:data:`OPTIONAL_KEYS`, written only when set, so a record without them reads and applies as
before) model what the quadratic fall-off about a camera-frame axis leaves out: ``falloff``, a ``cos^4`` fall-off
about two back-to-back lens axes ``+-direction`` (any unit camera-frame vector: a decentred lens or stitch), gain
``1 - edge_loss * (1 - cos(theta') ** 4)``; ``seam``, the two lenses' own gains ``[front, back]`` (front = the lens
looking along ``+direction``) cross-faded linearly over a band ``blend_deg`` wide about the seam plane; and
``chromatic``, factors ``[kR, kG, kB]`` of both fall-offs' losses per channel.  The response may also be
``"s-curve-K"``: sRGB, then an S-shaped tone curve of contrast ``K`` (:func:`contrast_of`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import asdict, dataclass, field

import numpy as np

from reconstruction.params import REQUIRED, ParamError, from_mapping, param, shown
from reconstruction.photometry import srgb_to_linear

__all__ = ["Photometric", "AXES", "KEYS", "OPTIONAL_KEYS", "gamma_of", "contrast_of", "is_response", "RESPONSES",
           "CameraDistribution", "LATER_FIELDS", "noise_parameters", "SHOT_FRACTION", "lens_direction"]

AXES = ("x", "y", "z")
RESPONSES = "'srgb', 'gamma-G' with G in [1, 4] or 's-curve-K' with K in [1, 4]"
"""The response curves a record or a suite may name (for error messages)."""
UNIT_TOLERANCE = 1e-6
"""How far from 1 the length of a recorded lens ``direction`` may be."""


def _is_unit(v: tuple[float, ...]) -> bool:
    return abs(math.sqrt(sum(x * x for x in v)) - 1.0) <= UNIT_TOLERANCE


_UNIT = "a unit vector [x, y, z] in the camera frame"


# The record as frame.json has it, for checking (Photometric.from_json); the fields' meanings: Photometric's.
@dataclass(frozen=True)
class _Vignetting:
    axis: str = param(REQUIRED, choices=AXES)
    edge_loss: float = param(REQUIRED, limits=(0.0, 0.999))


@dataclass(frozen=True)
class _Noise:
    shot: float = param(REQUIRED, limits=(0.0, 1.0))
    read: float = param(REQUIRED, limits=(0.0, 1.0))


@dataclass(frozen=True)
class _Falloff:
    direction: tuple[float, float, float] = param(REQUIRED, valid=_is_unit, expects=_UNIT)
    edge_loss: float = param(REQUIRED, limits=(0.0, 0.999))


@dataclass(frozen=True)
class _Seam:
    direction: tuple[float, float, float] = param(REQUIRED, valid=_is_unit, expects=_UNIT)
    gains: tuple[float, float] = param(REQUIRED, limits=(0.05, 20.0))
    blend_deg: float = param(REQUIRED, unit="degrees", limits=(0.0, 90.0), exclusive=(True, False))


@dataclass(frozen=True)
class _Record:
    exposure_stops: float = param(REQUIRED, limits=(-8.0, 8.0))
    white_balance: tuple[float, float, float] = param(REQUIRED, limits=(0.05, 20.0))
    vignetting: _Vignetting = param(REQUIRED)
    noise: _Noise = param(REQUIRED)
    response: str = param(REQUIRED, valid=lambda r: is_response(r), expects=RESPONSES)
    jpeg_quality: int = param(REQUIRED, limits=(0, 100))
    seed: int = param(REQUIRED, limits=(0, 2 ** 63), exclusive=(False, True))
    falloff: _Falloff | None = None
    seam: _Seam | None = None
    chromatic: tuple[float, float, float] | None = param(None, limits=(0.0, 4.0))


KEYS = tuple(f.name for f in dataclasses.fields(_Record) if f.default is REQUIRED)
"""The keys of a record (``exposure_stops``, ``white_balance``, ``vignetting``, ``noise``, ``response``,
``jpeg_quality``, ``seed``)."""
OPTIONAL_KEYS = tuple(f.name for f in dataclasses.fields(_Record) if f.default is not REQUIRED)
"""Keys a record may leave out (``falloff``, ``seam``, ``chromatic``; absent = that effect is off);
:meth:`Photometric.to_json` writes them only when set."""


@dataclass(frozen=True)
class Photometric:
    """One camera's photometric response (module doc).

    Attributes:
        exposure_stops: exposure offset against the ideal render, stops (``2 ** e`` in linear light).
        white_balance: (R, G, B) gains in linear light.
        vignetting: ``{"axis": "y", "edge_loss": 0.25}``: the lens axis in the camera frame and the fraction of
            light lost at the lenses' seam; ``edge_loss`` 0 = none.
        noise: ``{"shot": a, "read": b}``: the noise variance ``a * x + b`` at linear level ``x`` (0, 0 = none).
        response: ``"srgb"``, ``"gamma-G"`` or ``"s-curve-K"`` with G, K in [1, 4] (:func:`contrast_of`).
        jpeg_quality: 1-100, or 0 for no compression.
        seed: the noise generator's seed.
        falloff: None (off) or ``{"direction": [x, y, z], "edge_loss": L}``: a ``cos^4`` fall-off about the lens
            axes ``+-direction`` (unit camera-frame vector), gain ``1 - L * (1 - cos(theta') ** 4)``, ``theta'``
            the angle from the nearer axis; the seam (90 degrees from both) loses ``L`` (fraction).
        seam: None (off) or ``{"direction": [x, y, z], "gains": [front, back], "blend_deg": w}``: the lens
            looking along ``+direction`` has gain ``front``, the other ``back``; across the band ``|phi| <= w / 2``
            degrees about the seam plane (``phi = asin(bearing . direction)``) the gain is cross-faded linearly.
        chromatic: None (off) or ``(kR, kG, kB)``: channel ``c`` loses ``k_c`` times the light ``vignetting`` and
            ``falloff`` lose (``k_c * edge_loss`` at the seam, at most 0.999).
    """

    exposure_stops: float = 0.0
    white_balance: tuple[float, float, float] = (1.0, 1.0, 1.0)
    vignetting: dict = field(default_factory=lambda: {"axis": "y", "edge_loss": 0.0})
    noise: dict = field(default_factory=lambda: {"shot": 0.0, "read": 0.0})
    response: str = "srgb"
    jpeg_quality: int = 0
    seed: int = 0
    falloff: dict | None = None
    seam: dict | None = None
    chromatic: tuple[float, float, float] | None = None

    def to_json(self) -> dict:
        """The ``frame.json`` object: every key of :data:`KEYS`, and those of :data:`OPTIONAL_KEYS` that are set."""
        out = asdict(self)
        out["white_balance"] = [float(g) for g in self.white_balance]
        for k in OPTIONAL_KEYS:
            if out[k] is None:
                del out[k]
        if self.chromatic is not None:
            out["chromatic"] = [float(k) for k in self.chromatic]
        return out

    @classmethod
    def from_json(cls, raw, where: str = "photometric") -> Photometric:
        """Read and check a record: every key of :data:`KEYS`, each valid, and no other; the keys of
        :data:`OPTIONAL_KEYS` may be left out (:func:`reconstruction.params.from_mapping` on :class:`_Record`:
        unknown keys first, then the values present, then missing keys).

        Raises:
            ParamError: one line naming ``where`` and the bad, unknown or missing key
                (``cameras.U.photometric: noise.shot: expected a number in [0, 1], got -1``).
        """
        r = from_mapping(_Record, raw, where=where)
        if r.chromatic is not None:
            loss = max(r.vignetting.edge_loss, r.falloff.edge_loss if r.falloff else 0.0)
            if max(r.chromatic) * loss > 0.999:
                raise ParamError("chromatic", f"factors of at most {0.999 / loss:g} (times the largest edge_loss, "
                                 f"{loss:g}, they may lose at most 0.999 of a channel's light)",
                                 shown(raw["chromatic"]), where)
        falloff = None if r.falloff is None else {"direction": list(r.falloff.direction),
                                                  "edge_loss": r.falloff.edge_loss}
        seam = None if r.seam is None else {"direction": list(r.seam.direction), "gains": list(r.seam.gains),
                                            "blend_deg": r.seam.blend_deg}
        return cls(r.exposure_stops, r.white_balance, dataclasses.asdict(r.vignetting), dataclasses.asdict(r.noise),
                   r.response, r.jpeg_quality, r.seed, falloff, seam, r.chromatic)

    @property
    def is_ideal(self) -> bool:
        """Whether :func:`apply` leaves an image unchanged."""
        return (self.exposure_stops == 0.0 and tuple(self.white_balance) == (1.0, 1.0, 1.0)
                and self.vignetting["edge_loss"] == 0.0 and self.noise["shot"] == 0.0 and self.noise["read"] == 0.0
                and self.response == "srgb" and self.jpeg_quality == 0
                and (self.falloff is None or self.falloff["edge_loss"] == 0.0)
                and (self.seam is None or tuple(self.seam["gains"]) == (1.0, 1.0)))


def _curve_parameter(response: str, prefix: str) -> float | None:
    """The number after ``prefix`` in ``response`` when it is finite and in [1, 4], else None."""
    if not response.startswith(prefix):
        return None
    try:
        x = float(response[len(prefix):])
    except ValueError:
        return None
    return x if math.isfinite(x) and 1.0 <= x <= 4.0 else None


def gamma_of(response: str) -> float | None:
    """G of a ``"gamma-G"`` response with G in [1, 4], else None."""
    return _curve_parameter(response, "gamma-")


def contrast_of(response: str) -> float | None:
    """K of an ``"s-curve-K"`` response with K in [1, 4], else None.

    The response is sRGB encoding followed by the S curve ``s ** K / (s ** K + (1 - s) ** K)`` on the encoded value
    ``s`` in [0, 1]: smooth, increasing, fixed points 0, 1/2 and 1, slope ``K`` at mid-grey (1 = plain sRGB): a
    camera's "vivid" tone curve, darker shadows and brighter highlights than sRGB.
    """
    return _curve_parameter(response, "s-curve-")


def is_response(response) -> bool:
    """Whether ``response`` names a response curve (:data:`RESPONSES`)."""
    return isinstance(response, str) and (
        response == "srgb" or gamma_of(response) is not None or contrast_of(response) is not None)


def lens_direction(axis: str, tilt_deg: float, azimuth_rad: float) -> list[float]:
    """The unit camera-frame vector ``tilt_deg`` degrees from the camera-frame ``axis``, towards azimuth
    ``azimuth_rad`` about it (0: towards the next axis, x -> y -> z -> x; pi / 2: towards ``axis`` x that one)."""
    a = np.eye(3)[AXES.index(axis)]
    u = np.eye(3)[(AXES.index(axis) + 1) % 3]
    v = np.cross(a, u)
    t = math.radians(tilt_deg)
    d = math.cos(t) * a + math.sin(t) * (math.cos(azimuth_rad) * u + math.sin(azimuth_rad) * v)
    return [float(x) for x in d / np.linalg.norm(d)]


SHOT_FRACTION = 0.8
"""Share of the noise variance at mid-grey that is shot (Poisson) noise."""


def noise_parameters(grey_levels: float) -> tuple[float, float]:
    """``(shot, read)`` of the linear-light noise variance ``shot * x + read`` whose sRGB standard deviation at
    mid-grey (sRGB 128) is ``grey_levels`` 8-bit levels, :data:`SHOT_FRACTION` of that variance shot noise."""
    x_mid = float(srgb_to_linear(np.array([128], np.uint8))[0])
    slope = 1.055 / 2.4 * x_mid ** (1.0 / 2.4 - 1.0)  # d sRGB / d linear at mid-grey (sRGB in [0, 1])
    var = (grey_levels / 255.0 / slope) ** 2
    return SHOT_FRACTION * var / x_mid, (1.0 - SHOT_FRACTION) * var


@dataclass(frozen=True)
class CameraDistribution:
    """The distribution each camera of a ``captured`` frame is drawn from (every range is uniform, inclusive).

    Attributes:
        exposure_stops: each camera's exposure offset is uniform in ``[-x, x]``, stops (independent metering).
        white_balance: red and blue gains ``(1 + x) ** g``, ``g`` uniform in [-1, 1] each (green 1).
        vignetting: ``[lo, hi]`` light lost at the lenses' seam (fraction).
        vignetting_axis: the lenses' axis in the camera frame (``"y"``: front and back).
        noise_grey_levels: ``[lo, hi]`` noise standard deviation at mid-grey, 8-bit levels.
        response: every camera's response curve (:data:`RESPONSES`), unless ``responses`` is given.
        jpeg_quality: ``[lo, hi]`` JPEG quality (integers; 0 0 = none).
        rotation_deg: ``[lo, hi]`` calibration error of U's and R's told orientation, degrees (0 0 = none).
        translation_mm: ``[lo, hi]`` calibration error of U's and R's told position, millimetres (0 0 = none).

    The limits of each (and its type) are its field's (:func:`reconstruction.params.param`), which a suite's
    ``[conditions.<name>]`` table is checked against (``harness.data.suite``).

    The keys below came after ``tri360-v2``; each is off at its default, and :meth:`to_json` leaves it out then (so
    the record of a distribution without them is what it was):

    Attributes (after tri360-v2):
        falloff: ``[lo, hi]`` light the ``cos^4`` fall-off (``Photometric.falloff``) loses at the seam (0 0 = none).
        lens_tilt_deg: ``[lo, hi]`` angle between the lens axis of ``falloff`` and ``seam`` and
            ``vignetting_axis``, degrees, towards a uniform azimuth (0 0 = the lenses look along the axis).
        lens_mismatch: ``[lo, hi]`` relative gain difference ``delta`` of the two lenses: gains ``(1 + delta) **
            (+-1/2)``, the brighter lens front or back with equal odds (0 0 = none).
        seam_blend_deg: ``[lo, hi]`` width of the band over which the stitch cross-fades the two lenses, degrees
            (with ``lens_mismatch`` only).
        chromatic: ``[lo, hi]``: the fall-offs' losses scaled by ``(1 + c, 1, 1 - c)`` in (R, G, B), ``c`` drawn
            (0 0 = none).
        responses: each camera's response curve drawn uniformly from these (empty: every camera ``response``).
        held_out: no selection may use the condition; results report it only (not a property of the cameras: the
            draw ignores it).
    """

    exposure_stops: float = param(0.5, limits=(0.0, 8.0))
    white_balance: float = param(0.05, limits=(0.0, 10.0))
    vignetting: tuple[float, float] = param((0.15, 0.35), limits=(0.0, 0.999), ordered=True)
    vignetting_axis: str = param("y", choices=AXES)
    noise_grey_levels: tuple[float, float] = param((1.0, 3.0), limits=(0.0, 128.0), ordered=True)
    response: str = param("srgb", valid=lambda r: is_response(r), expects=RESPONSES)
    jpeg_quality: tuple[int, int] = param((85, 95), limits=(0, 100), ordered=True)
    rotation_deg: tuple[float, float] = param((0.1, 0.3), limits=(0.0, 45.0), ordered=True)
    translation_mm: tuple[float, float] = param((1.0, 2.0), limits=(0.0, 1000.0), ordered=True)
    falloff: tuple[float, float] = param((0.0, 0.0), limits=(0.0, 0.999), ordered=True)
    lens_tilt_deg: tuple[float, float] = param((0.0, 0.0), limits=(0.0, 90.0), ordered=True)
    lens_mismatch: tuple[float, float] = param((0.0, 0.0), limits=(0.0, 1.0), ordered=True)
    seam_blend_deg: tuple[float, float] = param((0.0, 0.0), limits=(0.0, 90.0), ordered=True)
    chromatic: tuple[float, float] = param((0.0, 0.0), limits=(0.0, 0.9), ordered=True)
    responses: tuple[str, ...] = param((), valid=lambda rs: bool(rs) and all(map(is_response, rs)),
                                       expects=f"a non-empty list of {RESPONSES}")
    held_out: bool = False

    def to_json(self) -> dict:
        """The distribution as recorded (a twin's ``renderer.condition.distribution``, results' suite record):
        every field, but those of :data:`LATER_FIELDS` only when not at their default."""
        out = dataclasses.asdict(self)
        for k in LATER_FIELDS:
            if out[k] == _OFF[k]:
                del out[k]
        return out

    def draw(self, rng: np.random.Generator) -> Photometric:
        """One camera's :class:`Photometric` (its noise seed drawn from ``rng`` too).

        The keys of ``tri360-v2`` are drawn first, in their order; then, only for the keys that are on: the lens
        axis (tilt, azimuth), ``falloff``, ``lens_mismatch`` (size, sign, blend width), ``chromatic``, the response
        (so a distribution without them draws what it always drew).
        """
        e = float(rng.uniform(-self.exposure_stops, self.exposure_stops))
        g = rng.uniform(-1.0, 1.0, size=2)
        wb = (float((1.0 + self.white_balance) ** g[0]), 1.0, float((1.0 + self.white_balance) ** g[1]))
        loss = float(rng.uniform(*self.vignetting))
        shot, read = noise_parameters(float(rng.uniform(*self.noise_grey_levels)))
        lo, hi = self.jpeg_quality
        q = int(rng.integers(lo, hi + 1))
        seed = int(rng.integers(0, 2 ** 62))
        falloff = seam = chromatic = None
        response = self.response
        if self.falloff[1] > 0 or self.lens_mismatch[1] > 0:
            tilt = float(rng.uniform(*self.lens_tilt_deg))
            d = lens_direction(self.vignetting_axis, tilt, float(rng.uniform(0.0, 2.0 * math.pi)))
            if self.falloff[1] > 0:
                falloff = {"direction": list(d), "edge_loss": float(rng.uniform(*self.falloff))}
            if self.lens_mismatch[1] > 0:
                delta = float(rng.uniform(*self.lens_mismatch))
                sign = 1.0 if rng.integers(0, 2) else -1.0
                gains = [float((1.0 + delta) ** (0.5 * sign)), float((1.0 + delta) ** (-0.5 * sign))]
                seam = {"direction": list(d), "gains": gains, "blend_deg": float(rng.uniform(*self.seam_blend_deg))}
        if self.chromatic[1] > 0:
            c = float(rng.uniform(*self.chromatic))
            chromatic = (1.0 + c, 1.0, 1.0 - c)
        if self.responses:
            response = self.responses[int(rng.integers(0, len(self.responses)))]
        return Photometric(e, wb, {"axis": self.vignetting_axis, "edge_loss": loss}, {"shot": shot, "read": read},
                           response, q, seed, falloff, seam, chromatic)


LATER_FIELDS = ("falloff", "lens_tilt_deg", "lens_mismatch", "seam_blend_deg", "chromatic", "responses", "held_out")
"""The :class:`CameraDistribution` fields added after ``tri360-v2`` (recorded only when not at their default)."""
_OFF = {k: v for k, v in dataclasses.asdict(CameraDistribution()).items() if k in LATER_FIELDS}
