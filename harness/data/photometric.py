"""The photometric record of one camera in ``frame.json`` (``cameras.<name>.photometric``).

A camera without one is ideal: its PNG is the scene-linear light encoded as sRGB.  A real camera meters its own
exposure and white balance, its lenses darken towards their edges, its sensor adds noise, its response curve and
encoder shape the bytes; :class:`Photometric` records each of these, and ``harness.render.camera.apply`` turns an
ideal image into that camera's image, in linear light, in this order: vignetting (gain
``1 - edge_loss * (theta / 90 deg) ** 2``, ``theta`` the angle from the nearer of the two back-to-back lens axes
``+-axis``), exposure (``2 ** exposure_stops``), white balance (R, G, B gains), noise (variance
``shot * x + read`` at linear level ``x``, seeded with ``seed``), the response curve (``"srgb"`` or ``"gamma-G"``),
JPEG at ``jpeg_quality`` (0 = none).  A record in a file has every key of :data:`KEYS` (none takes a default).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from reconstruction.photometry import srgb_to_linear

__all__ = ["Photometric", "AXES", "KEYS", "gamma_of", "CameraDistribution", "noise_parameters", "SHOT_FRACTION"]

AXES = ("x", "y", "z")
KEYS = ("exposure_stops", "white_balance", "vignetting", "noise", "response", "jpeg_quality", "seed")


@dataclass(frozen=True)
class Photometric:
    """One camera's photometric response (module doc).

    Attributes:
        exposure_stops: exposure offset against the ideal render, stops (``2 ** e`` in linear light).
        white_balance: (R, G, B) gains in linear light.
        vignetting: ``{"axis": "y", "edge_loss": 0.25}``: the lens axis in the camera frame and the fraction of
            light lost at the lenses' seam; ``edge_loss`` 0 = none.
        noise: ``{"shot": a, "read": b}``: the noise variance ``a * x + b`` at linear level ``x`` (0, 0 = none).
        response: ``"srgb"`` or ``"gamma-G"`` with G in [1, 4].
        jpeg_quality: 1-100, or 0 for no compression.
        seed: the noise generator's seed.
    """

    exposure_stops: float = 0.0
    white_balance: tuple[float, float, float] = (1.0, 1.0, 1.0)
    vignetting: dict = field(default_factory=lambda: {"axis": "y", "edge_loss": 0.0})
    noise: dict = field(default_factory=lambda: {"shot": 0.0, "read": 0.0})
    response: str = "srgb"
    jpeg_quality: int = 0
    seed: int = 0

    def to_json(self) -> dict:
        out = asdict(self)
        out["white_balance"] = [float(g) for g in self.white_balance]
        return out

    @classmethod
    def from_json(cls, raw, where: str = "photometric") -> Photometric:
        """Read and check a record: every key of :data:`KEYS`, each valid, and no other (the keys present are
        checked first, then that none is missing).

        Raises:
            ValueError: one line naming ``where`` and the bad, unknown or missing key(s).
        """
        if not isinstance(raw, dict):
            raise ValueError(f"{where} must be an object, got {type(raw).__name__}")
        unknown = sorted(set(raw) - set(KEYS))
        if unknown:
            raise ValueError(f"{where}: unknown key(s) {', '.join(unknown)} (known: {', '.join(KEYS)})")

        def number(key, value, lo, hi):
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value) \
                    or not lo <= value <= hi:
                raise ValueError(f"{where}.{key} must be a number in [{lo:g}, {hi:g}], got {value!r}")
            return float(value)

        d = cls()
        e = number("exposure_stops", raw.get("exposure_stops", d.exposure_stops), -8.0, 8.0)
        wb = raw.get("white_balance", list(d.white_balance))
        if not isinstance(wb, list | tuple) or len(wb) != 3:
            raise ValueError(f"{where}.white_balance must be three gains [R, G, B], got {wb!r}")
        wb = tuple(number("white_balance", g, 0.05, 20.0) for g in wb)
        vig = raw.get("vignetting", d.vignetting)
        if not isinstance(vig, dict) or set(vig) != {"axis", "edge_loss"} or vig["axis"] not in AXES:
            raise ValueError(f"{where}.vignetting must be {{\"axis\": one of x, y, z, \"edge_loss\": number}}, "
                             f"got {vig!r}")
        vig = {"axis": vig["axis"], "edge_loss": number("vignetting.edge_loss", vig["edge_loss"], 0.0, 0.999)}
        noise = raw.get("noise", d.noise)
        if not isinstance(noise, dict) or set(noise) != {"shot", "read"}:
            raise ValueError(f"{where}.noise must be {{\"shot\": number, \"read\": number}}, got {noise!r}")
        noise = {k: number(f"noise.{k}", noise[k], 0.0, 1.0) for k in ("shot", "read")}
        response = raw.get("response", d.response)
        if not isinstance(response, str) or not (response == "srgb" or gamma_of(response) is not None):
            raise ValueError(f"{where}.response must be 'srgb' or 'gamma-G' with G in [1, 4], got {response!r}")
        q = raw.get("jpeg_quality", d.jpeg_quality)
        if isinstance(q, bool) or not isinstance(q, int) or not 0 <= q <= 100:
            raise ValueError(f"{where}.jpeg_quality must be an integer 0-100 (0 = none), got {q!r}")
        seed = raw.get("seed", d.seed)
        if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2 ** 63:
            raise ValueError(f"{where}.seed must be a non-negative integer, got {seed!r}")
        missing = [k for k in KEYS if k not in raw]
        if missing:
            raise ValueError(f"{where}: missing key(s) {', '.join(missing)} (a photometric record needs every key: "
                             f"{', '.join(KEYS)})")
        return cls(e, wb, vig, noise, response, q, seed)

    @property
    def is_ideal(self) -> bool:
        """Whether :func:`apply` leaves an image unchanged."""
        return (self.exposure_stops == 0.0 and tuple(self.white_balance) == (1.0, 1.0, 1.0)
                and self.vignetting["edge_loss"] == 0.0 and self.noise["shot"] == 0.0 and self.noise["read"] == 0.0
                and self.response == "srgb" and self.jpeg_quality == 0)


def gamma_of(response: str) -> float | None:
    """G of a ``"gamma-G"`` response with G in [1, 4], else None."""
    if not response.startswith("gamma-"):
        return None
    try:
        g = float(response[len("gamma-"):])
    except ValueError:
        return None
    return g if math.isfinite(g) and 1.0 <= g <= 4.0 else None


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
        response: the response curve (``"srgb"`` or ``"gamma-G"``).
        jpeg_quality: ``[lo, hi]`` JPEG quality (integers; 0 0 = none).
        rotation_deg: ``[lo, hi]`` calibration error of U's and R's told orientation, degrees (0 0 = none).
        translation_mm: ``[lo, hi]`` calibration error of U's and R's told position, millimetres (0 0 = none).
    """

    exposure_stops: float = 0.5
    white_balance: float = 0.05
    vignetting: tuple[float, float] = (0.15, 0.35)
    vignetting_axis: str = "y"
    noise_grey_levels: tuple[float, float] = (1.0, 3.0)
    response: str = "srgb"
    jpeg_quality: tuple[int, int] = (85, 95)
    rotation_deg: tuple[float, float] = (0.1, 0.3)
    translation_mm: tuple[float, float] = (1.0, 2.0)

    def draw(self, rng: np.random.Generator) -> Photometric:
        """One camera's :class:`Photometric` (its noise seed drawn from ``rng`` too)."""
        e = float(rng.uniform(-self.exposure_stops, self.exposure_stops))
        g = rng.uniform(-1.0, 1.0, size=2)
        wb = (float((1.0 + self.white_balance) ** g[0]), 1.0, float((1.0 + self.white_balance) ** g[1]))
        loss = float(rng.uniform(*self.vignetting))
        shot, read = noise_parameters(float(rng.uniform(*self.noise_grey_levels)))
        lo, hi = self.jpeg_quality
        q = int(rng.integers(lo, hi + 1))
        seed = int(rng.integers(0, 2 ** 62))
        return Photometric(e, wb, {"axis": self.vignetting_axis, "edge_loss": loss}, {"shot": shot, "read": read},
                           self.response, q, seed)
