"""Camera families beyond tri360-v2's ``captured`` cameras (suite tri360-v3): an off-centre ``cos^4`` fall-off, two
fisheyes with their own gains and a blended seam, chromatic vignetting, response curves that differ between cameras
(S curves), low light; the ``held_out`` condition key; and tri360-v2's twins, which must stay what they were.

Every suite rendered here uses the ray-cast synthetic_box family at 96 px: no Blender."""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from harness.cli import main
from harness.commands.parts.captured import captured_twin, twin_generator
from harness.commands.parts.suite import check_suite_data, evaluate_suite, load
from harness.data.errors import UserError
from harness.data.frame import read_frame
from harness.data.photometric import (
    KEYS,
    LATER_FIELDS,
    OPTIONAL_KEYS,
    CameraDistribution,
    Photometric,
    gamma_of,
    lens_direction,
    noise_parameters,
)
from harness.render.camera import apply, encode, falloff_gain, lens_gain, s_curve, seam_gain, vignetting_gain
from harness.runtime.context import QUIET
from reconstruction.camera.equirect import bearing_grid
from reconstruction.methods.registry import get_methods
from reconstruction.photometry import linear_to_srgb, srgb_to_linear
from tests.helpers import make_synthetic_frame

SUITES = Path(__file__).resolve().parents[3] / "suites"
V2_KEYS = ["exposure_stops", "white_balance", "vignetting", "vignetting_axis", "noise_grey_levels", "response",
           "jpeg_quality", "rotation_deg", "translation_mm"]
"""The keys of a tri360-v2 condition's record (``renderer.condition.distribution``), in their order."""
TILTED = lens_direction("y", 20.0, 0.7)


# ------------------------------------------------------------------------------ tri360-v2 stays what it was


def _v2_draw(dist: CameraDistribution, rng: np.random.Generator) -> dict:
    """``CameraDistribution.draw`` as of tri360-v2 (frozen copy), as a record."""
    e = float(rng.uniform(-dist.exposure_stops, dist.exposure_stops))
    g = rng.uniform(-1.0, 1.0, size=2)
    wb = [float((1.0 + dist.white_balance) ** g[0]), 1.0, float((1.0 + dist.white_balance) ** g[1])]
    loss = float(rng.uniform(*dist.vignetting))
    shot, read = noise_parameters(float(rng.uniform(*dist.noise_grey_levels)))
    lo, hi = dist.jpeg_quality
    q = int(rng.integers(lo, hi + 1))
    seed = int(rng.integers(0, 2 ** 62))
    return {"exposure_stops": e, "white_balance": wb, "vignetting": {"axis": dist.vignetting_axis, "edge_loss": loss},
            "noise": {"shot": shot, "read": read}, "response": dist.response, "jpeg_quality": q, "seed": seed}


def _v2_apply(image: np.ndarray, p: dict) -> np.ndarray:
    """``harness.render.camera.apply`` as of tri360-v2 (frozen copy), on a record."""
    h, w = image.shape[:2]
    lin = srgb_to_linear(image).astype(np.float64)
    if p["vignetting"]["edge_loss"] > 0:
        c = np.abs(bearing_grid(w, h)[..., "xyz".index(p["vignetting"]["axis"])])
        theta = np.arccos(np.clip(c, 0.0, 1.0))
        lin *= (1.0 - p["vignetting"]["edge_loss"] * (theta / (np.pi / 2.0)) ** 2).astype(np.float32)[..., None]
    lin *= (2.0 ** p["exposure_stops"]) * np.asarray(p["white_balance"], np.float64)
    a, b = p["noise"]["shot"], p["noise"]["read"]
    if a > 0 or b > 0:
        rng = np.random.default_rng(p["seed"])
        lin = lin + np.sqrt(a * np.clip(lin, 0.0, None) + b) * rng.standard_normal(lin.shape)
    if p["response"] == "srgb":
        out = linear_to_srgb(lin)
    else:
        x = np.clip(np.nan_to_num(lin, nan=0.0), 0.0, 1.0)
        out = np.floor(np.power(x, 1.0 / gamma_of(p["response"])) * 255.0 + 0.5).astype(np.uint8)
    if p["jpeg_quality"] > 0:
        _, buf = cv2.imencode(".jpg", cv2.cvtColor(out, cv2.COLOR_RGB2BGR),
                              [cv2.IMWRITE_JPEG_QUALITY, int(p["jpeg_quality"])])
        out = cv2.cvtColor(cv2.imdecode(buf, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    return out


def test_the_published_v2_suite_file_is_unchanged():
    assert hashlib.sha256((SUITES / "tri360-v2.toml").read_bytes()).hexdigest() == (
        "282d1f0c405609e444394e47c5e5d6ee029ccb4d9149ed4241b8b04ae22c090c")


@pytest.mark.parametrize("response", ["srgb", "gamma-2.2"])
def test_a_v2_twin_is_what_tri360_v2_derived(response):
    """The twin under tri360-v2's condition (and one with a gamma response): every camera's record is the frozen v2
    draw, bit for bit, and written with the v2 keys only; every image is the frozen v2 model's, byte for byte; the
    condition's record has exactly the v2 keys."""
    dist = load(SUITES / "tri360-v2.toml").conditions["captured"]
    if response != "srgb":
        dist = CameraDistribution(response=response)
    frame = make_synthetic_frame(64)
    seed = 1001 * 1000 + 7
    twin = captured_twin(frame, dist, seed)
    record = json.loads(json.dumps(twin.renderer["condition"]["distribution"]))
    assert list(record) == V2_KEYS and record["vignetting"] == [0.15, 0.35]
    for k in "CUR":
        want = _v2_draw(dist, twin_generator(seed, "photometric", k))
        got = twin.photometric[k].to_json()
        assert list(got) == list(KEYS) and got == want, k
        np.testing.assert_array_equal(twin.images[k], _v2_apply(frame.images[k], want), err_msg=k)


def test_a_distribution_draws_the_v2_keys_first_and_records_later_keys_only_when_set():
    v2 = CameraDistribution()
    v3 = CameraDistribution(falloff=(0.1, 0.2), lens_tilt_deg=(10.0, 30.0), lens_mismatch=(0.03, 0.1),
                            seam_blend_deg=(2.0, 6.0), chromatic=(0.1, 0.3), responses=("gamma-1.8", "s-curve-1.5"),
                            held_out=True)
    for seed in range(20):
        a, b = v2.draw(np.random.default_rng(seed)), v3.draw(np.random.default_rng(seed))
        assert all(getattr(a, k) == getattr(b, k) for k in KEYS if k != "response")
        assert a.falloff is a.seam is a.chromatic is None and b.falloff and b.seam and b.chromatic
    assert list(v2.to_json()) == V2_KEYS
    assert list(v3.to_json()) == V2_KEYS + list(LATER_FIELDS) and v3.to_json()["held_out"] is True


# ----------------------------------------------------------------------------------------- the record


def _full_record() -> Photometric:
    dist = CameraDistribution(falloff=(0.1, 0.2), lens_tilt_deg=(10.0, 30.0), lens_mismatch=(0.03, 0.1),
                              seam_blend_deg=(2.0, 6.0), chromatic=(0.1, 0.3), responses=("s-curve-1.5",))
    return dist.draw(np.random.default_rng(4))


def test_the_record_round_trips_with_every_optional_key():
    p = _full_record()
    raw = json.loads(json.dumps(p.to_json()))
    assert list(raw) == list(KEYS) + list(OPTIONAL_KEYS) and raw["response"] == "s-curve-1.5"
    assert Photometric.from_json(raw) == p
    assert Photometric.from_json(json.loads(json.dumps(Photometric().to_json()))) == Photometric()
    assert list(Photometric().to_json()) == list(KEYS)
    assert not Photometric(response="s-curve-1.5").is_ideal
    assert not Photometric(falloff={"direction": TILTED, "edge_loss": 0.2}).is_ideal
    assert not Photometric(seam={"direction": [0.0, 1.0, 0.0], "gains": [1.05, 0.95], "blend_deg": 4.0}).is_ideal
    assert Photometric(falloff={"direction": TILTED, "edge_loss": 0.0}, chromatic=(1.2, 1.0, 0.8)).is_ideal


@pytest.mark.parametrize("key, value, culprit", [
    ("falloff", {"direction": [0.0, 1.0, 0.1], "edge_loss": 0.2}, r"falloff\.direction: expected a unit vector"),
    ("falloff", {"direction": [0.0, 1.0, 0.0], "edge_loss": 1.5},
     r"falloff\.edge_loss: expected a number in \[0, 0\.999\], got 1\.5$"),
    ("falloff", {"direction": [0.0, 1.0, 0.0], "edge_loss": 0.2, "k": 1},
     r"falloff\.k: expected one of the keys direction, edge_loss, got an unknown key$"),
    ("seam", {"direction": [0.0, 1.0, 0.0], "gains": [1.0, 1.0, 1.0], "blend_deg": 4},
     r"seam\.gains: expected 2 numbers"),
    ("seam", {"direction": [0.0, 1.0, 0.0], "gains": [1.0, 0.0], "blend_deg": 4},
     r"seam\.gains: expected 2 numbers, each in \[0\.05, 20\]"),
    ("seam", {"direction": [0.0, 1.0, 0.0], "gains": [1.0, 0.9], "blend_deg": 0},
     r"seam\.blend_deg: expected a number in \(0, 90\], got 0$"),
    ("seam", {"direction": ["a", 1.0, 0.0], "gains": [1.0, 0.9], "blend_deg": 4},
     r"seam\.direction: expected a unit vector"),
    ("chromatic", [1.2, 1.0], r"chromatic: expected 3 numbers, each in \[0, 4\] or null, got \[1\.2, 1\.0\]$"),
    ("chromatic", [1.2, 1.0, -0.1], r"chromatic: expected 3 numbers, each in \[0, 4\]"),
    ("chromatic", [3.0, 1.0, 1.0],
     r"chromatic: expected factors of at most 2\.4975 \(times the largest edge_loss, 0\.4,"),
    ("response", "s-curve-9", r"response: expected 'srgb', 'gamma-G' .* or 's-curve-K' .*, got 's-curve-9'$"),
    ("response", "s-curve-x", r"response: expected 'srgb'"),
])
def test_bad_optional_keys_are_one_line_naming_the_key(key, value, culprit):
    raw = {**Photometric(vignetting={"axis": "y", "edge_loss": 0.4}).to_json(), key: value}
    with pytest.raises(ValueError, match=r"^cameras\.U\.photometric: " + culprit) as info:
        Photometric.from_json(raw, "cameras.U.photometric")
    assert "\n" not in str(info.value)


# ------------------------------------------------------------------------------------------ the families


def test_lens_direction_is_tilted_from_the_axis_by_the_angle():
    for axis in "xyz":
        for tilt, azimuth in ((0.0, 1.0), (10.0, 0.0), (30.0, 4.0)):
            d = np.asarray(lens_direction(axis, tilt, azimuth))
            assert np.linalg.norm(d) == pytest.approx(1.0, abs=1e-12)
            assert math.degrees(math.acos(d["xyz".index(axis)])) == pytest.approx(tilt, abs=1e-6)


def test_the_off_centre_falloff_is_cos4_about_the_tilted_axes():
    w, h, loss = 400, 200, 0.3
    g = falloff_gain(w, h, TILTED, loss)[..., 0]
    c = bearing_grid(w, h) @ np.asarray(TILTED)
    np.testing.assert_allclose(g, 1.0 - loss * (1.0 - c ** 4), atol=1e-6)  # the formula, float32
    # brightest on the lens axes +-d, darkest (1 - loss) on their seam, wherever that is
    top = bearing_grid(w, h)[np.unravel_index(np.argmax(g), g.shape)]
    assert math.degrees(math.acos(min(1.0, abs(float(top @ TILTED))))) < 1.0
    seam = np.abs(c) < 0.01
    assert seam.sum() > 100 and np.all(np.abs(g[seam] - (1.0 - loss)) < 1e-6)
    assert g.min() == pytest.approx(1.0 - loss, abs=1e-6) and g.max() == pytest.approx(1.0, abs=1e-4)
    # not the v2 vignetting: the image centre (+Y) is 20 degrees off the front lens's axis
    assert g[h // 2, w // 2] == pytest.approx(1.0 - loss * (1.0 - math.cos(math.radians(20.0)) ** 4), abs=2e-3)
    assert np.abs(g - vignetting_gain(w, h, "y", loss)).max() > 0.1


def test_the_seam_blend_is_continuous_and_each_lens_keeps_its_gain_away_from_it():
    w, h, front, back, blend = 1440, 720, 1.05, 0.95, 4.0
    g = seam_gain(w, h, [0.0, 1.0, 0.0], (front, back), blend)
    phi = np.degrees(np.arcsin(np.clip(bearing_grid(w, h)[..., 1], -1.0, 1.0)))
    np.testing.assert_allclose(g[phi > blend / 2], front, atol=1e-6)
    np.testing.assert_allclose(g[phi < -blend / 2], back, atol=1e-6)
    band = np.abs(phi) <= blend / 2
    np.testing.assert_allclose(g[band], back + (front - back) * (phi[band] / blend + 0.5), atol=1e-6)
    # continuous: neighbouring pixels (0.25 degrees apart) differ by at most the blend's slope times their spacing,
    # 16x less than the lenses' step
    step = 360.0 / w
    jumps = max(np.abs(np.diff(g, axis=1)).max(), np.abs(np.diff(g, axis=0)).max())
    assert jumps <= (front - back) / blend * step * 1.01 and jumps < (front - back) / 10
    # through the whole model: a flat image's two halves differ by the lenses' ratio (at sRGB ~150 one 8-bit code is
    # 1.6 % of the linear value: 2 % covers one code's rounding)
    flat = np.full((h // 4, w // 4, 3), 150, np.uint8)
    out = srgb_to_linear(apply(flat, Photometric(seam={"direction": [0.0, 1.0, 0.0], "gains": [front, back],
                                                       "blend_deg": blend})))
    centre, edge = out[h // 8, w // 8], out[h // 8, 0]  # looking +Y (front lens) and -Y (back lens)
    np.testing.assert_allclose(centre / edge, front / back, rtol=0.02)


def test_chromatic_vignetting_scales_each_channels_loss():
    w, h, loss, k = 400, 200, 0.3, (1.2, 1.0, 0.8)
    cam = Photometric(vignetting={"axis": "y", "edge_loss": loss}, chromatic=k)
    g = lens_gain(w, h, cam)
    shape = 1.0 - vignetting_gain(w, h, "y", 1.0).astype(np.float64)
    for c in range(3):
        np.testing.assert_allclose(g[..., c], 1.0 - k[c] * loss * shape, atol=1e-6)
    # at the seam (looking +X) red loses 0.36, green 0.30, blue 0.24 of the light; on the lens axis nothing
    flat = np.full((h, w, 3), 180, np.uint8)
    ratio = srgb_to_linear(apply(flat, cam)) / srgb_to_linear(flat)
    np.testing.assert_allclose(ratio[h // 2, 3 * w // 4], [0.64, 0.70, 0.76], atol=0.01)
    np.testing.assert_allclose(ratio[h // 2, w // 2], [1.0, 1.0, 1.0], atol=0.01)
    # the off-centre fall-off is scaled the same way, and the two fall-offs multiply
    both = Photometric(vignetting={"axis": "y", "edge_loss": loss}, chromatic=k,
                       falloff={"direction": TILTED, "edge_loss": 0.2})
    fall = falloff_gain(w, h, TILTED, 0.2 * np.asarray(k))
    np.testing.assert_allclose(lens_gain(w, h, both), g * fall, atol=1e-6)
    np.testing.assert_allclose(fall[..., 0], 1.0 - 0.2 * 1.2 * (1.0 - falloff_gain(w, h, TILTED, 1.0)[..., 0]),
                               atol=1e-6)


@pytest.mark.parametrize("k", [1.3, 1.5, 2.0, 4.0])
def test_the_s_curve_is_monotonic_with_fixed_ends_and_contrast_k(k):
    s = np.linspace(0.0, 1.0, 10001)
    y = s_curve(s, k)
    assert np.all(np.diff(y) > 0)
    assert (y[0], y[5000], y[-1]) == (0.0, pytest.approx(0.5, abs=1e-12), 1.0)
    slope = (s_curve(0.5 + 1e-6, k) - s_curve(0.5 - 1e-6, k)) / 2e-6
    assert slope == pytest.approx(k, rel=1e-6)
    low, high = (s > 0) & (s < 0.5), (s > 0.5) & (s < 1)
    assert np.all(y[low] < s[low]) and np.all(y[high] > s[high])  # S-shaped: darker shadows, brighter highlights
    np.testing.assert_allclose(s_curve(s, 1.0), s, atol=1e-12)


def test_a_response_mismatch_is_not_a_gain():
    """Two cameras with other response curves, read back as sRGB: the ratio of their linear values changes with the
    level (a gain would keep it constant), by far more than 8-bit rounding."""
    lin = np.linspace(0.05, 0.8, 64)[:, None].repeat(3, axis=1)
    srgb = srgb_to_linear(encode(lin, "srgb"))
    np.testing.assert_allclose(srgb, lin, rtol=0.02)
    for response in ("s-curve-1.5", "gamma-1.8", "gamma-2.4"):
        ratio = srgb_to_linear(encode(lin, response))[:, 1] / srgb[:, 1]
        assert ratio.max() / ratio.min() > 1.3, response
    assert np.abs(encode(lin, "s-curve-1").astype(int) - encode(lin, "srgb").astype(int)).max() <= 1
    # the S curve darkens the shadows and brightens the highlights against sRGB
    s = encode(lin, "s-curve-1.5").astype(int)[:, 0] - encode(lin, "srgb").astype(int)[:, 0]
    assert s[:10].max() < 0 < s[-10:].min()


def test_apply_with_every_family_is_deterministic():
    img = make_synthetic_frame(64).images["C"]
    p = _full_record()
    a, b = apply(img, p), apply(img, p)
    np.testing.assert_array_equal(a, b)
    assert a.shape == img.shape and a.dtype == np.uint8 and np.abs(a.astype(int) - img).mean() > 2


# ------------------------------------------------------------------------------------------- the suites


SUITE = """\
format = "tri360-suite/1"
name = "mini-families"

[render]
width = 96

[conditions.captured]
vignetting = [0.15, 0.35]

[conditions.offaxis]
vignetting = [0.0, 0.0]
falloff = [0.15, 0.35]
lens_tilt_deg = [10.0, 30.0]

[conditions.seams]
lens_mismatch = [0.03, 0.10]
seam_blend_deg = [2.0, 6.0]
held_out = true

[conditions.chromatic]
chromatic = [0.1, 0.3]

[conditions.tone]
responses = ["srgb", "gamma-1.8", "gamma-2.4", "s-curve-1.5"]
held_out = true

[conditions.lowlight]
noise_grey_levels = [4.0, 8.0]
jpeg_quality = [70, 95]

[[frames]]
family = "synthetic_box"
seed = 11
viewpoints = 1
split = "dev"
"""
CONDITIONS = ["captured", "offaxis", "seams", "chromatic", "tone", "lowlight"]


@pytest.mark.parametrize("old, new, culprit", [
    ("falloff = [0.15, 0.35]", "falloff = [0.35, 0.15]",
     r"conditions\.offaxis\.falloff: expected 2 numbers \(low <= high\)"),
    ("lens_tilt_deg = [10.0, 30.0]", "lens_tilt_deg = [10.0, 100.0]", r"offaxis\.lens_tilt_deg: expected 2 numbers"),
    ("falloff = [0.15, 0.35]\n", "", r"offaxis\.lens_tilt_deg: tilts the lens axis"),
    ("seam_blend_deg = [2.0, 6.0]", "seam_blend_deg = [0.0, 6.0]", r"seams\.seam_blend_deg: expected .* 0 < low"),
    ("lens_mismatch = [0.03, 0.10]\n", "", r"seams\.seam_blend_deg: is the width of the cross-fade"),
    ("lens_mismatch = [0.03, 0.10]", "lens_mismatch = [0.03, 2.0]",
     r"seams\.lens_mismatch: expected 2 numbers \(low <= high\), each in \[0, 1\]"),
    ("chromatic = [0.1, 0.3]", "chromatic = [0.1, 0.9]\nvignetting = [0.2, 0.6]",
     r"conditions\.chromatic\.chromatic: red's loss \(1 \+ 0\.9\) x the largest edge loss \(0\.6\)"),
    ("chromatic = [0.1, 0.3]", "chromatic = 0.2", r"chromatic\.chromatic: expected 2 numbers .*, got 0\.2$"),
    ('responses = ["srgb", "gamma-1.8", "gamma-2.4", "s-curve-1.5"]', "responses = []",
     r"tone\.responses: expected a non-empty list of 'srgb'.*, got \[\]$"),
    ('"s-curve-1.5"]', '"s-curve-0.5"]', r"tone\.responses: expected a non-empty list"),
    ('"s-curve-1.5"]', '"s-curve-1.5"]\nresponse = "srgb"', r"tone\.responses: .* leave response out"),
    ("[conditions.lowlight]", '[conditions.lowlight]\nresponse = "s-curve"', r"lowlight\.response: expected 'srgb'"),
    ("held_out = true\n\n[conditions.chromatic]", 'held_out = "yes"\n\n[conditions.chromatic]',
     r"seams\.held_out: expected true or false, got 'yes'$"),
    ("[conditions.lowlight]", "[conditions.lowlight]\nflare = 1",
     r"lowlight\.flare: expected one of the keys .*, got an unknown key$"),
])
def test_bad_family_keys_are_one_line_naming_file_and_key(tmp_path, old, new, culprit):
    assert old in SUITE
    path = tmp_path / "bad.toml"
    path.write_text(SUITE.replace(old, new, 1))
    with pytest.raises(UserError, match=culprit) as info:
        load(path)
    assert str(info.value).startswith(f"{path}: ") and "\n" not in str(info.value)


def test_the_shipped_v3_suite_is_v2s_frames_under_six_conditions_two_held_out():
    v2, v3 = load(SUITES / "tri360-v2.toml"), load(SUITES / "tri360-v3.toml")
    assert v3.name == "tri360-v3" and v3.id != v2.id
    assert v3.entries == v2.entries and v3.render == v2.render
    assert list(v3.conditions) == CONDITIONS and v3.conditions["captured"] == v2.conditions["captured"]
    assert v3.held_out_conditions() == ["seams", "tone"]
    assert v3.selectable_conditions() == ["ideal", "captured", "offaxis", "chromatic", "lowlight"]
    for split in ("dev", "test"):
        assert len(v3.frames(split)) == 7 * 48 and len(v2.frames(split)) == 2 * 48
    off, seams, chroma, tone, low = (v3.conditions[k] for k in CONDITIONS[1:])
    assert off.vignetting == (0.0, 0.0) and off.falloff == (0.15, 0.35) and off.lens_tilt_deg == (10.0, 30.0)
    assert seams.lens_mismatch == (0.03, 0.10) and seams.held_out and tone.held_out and len(tone.responses) > 2
    assert chroma.chromatic == (0.1, 0.3) and low.noise_grey_levels == (4.0, 8.0) and low.jpeg_quality == (70, 95)
    described = v3.describe("dev")["conditions"]
    assert described["tone"]["held_out"] is True and "held_out" not in described["offaxis"]
    assert described["captured"] == v2.describe("dev")["conditions"]["captured"]


def test_the_draws_of_the_v3_families_are_in_their_ranges():
    v3 = load(SUITES / "tri360-v3.toml").conditions
    responses = set()
    for seed in range(40):
        off, seams, chroma, tone = (v3[k].draw(twin_generator(seed, "photometric", "U"))
                                    for k in ("offaxis", "seams", "chromatic", "tone"))
        tilt = math.degrees(math.acos(abs(off.falloff["direction"][1])))
        assert 10.0 - 1e-9 <= tilt <= 30.0 + 1e-9 and 0.15 <= off.falloff["edge_loss"] <= 0.35
        assert off.vignetting["edge_loss"] == 0.0 and off.seam is None
        front, back = seams.seam["gains"]
        assert seams.seam["direction"] == [0.0, 1.0, 0.0] and front * back == pytest.approx(1.0)
        assert 1.03 - 1e-9 <= max(front / back, back / front) <= 1.10 + 1e-9
        assert 2.0 <= seams.seam["blend_deg"] <= 6.0
        kr, kg, kb = chroma.chromatic
        assert 1.1 <= kr <= 1.3 and kg == 1.0 and kb == pytest.approx(2.0 - kr)
        responses.add(tone.response)
        # paired conditions: a camera's exposure, white balance, noise seed, JPEG quality are the same under each
        assert len({(p.exposure_stops, p.white_balance, p.seed) for p in (off, seams, chroma, tone)}) == 1
    assert responses == set(v3["tone"].responses)


@pytest.mark.slow
def test_render_suite_derives_every_conditions_twins_and_evaluate_accepts_the_root(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(SUITE)
    root = tmp_path / "data"
    assert main(["render", "--suite", str(path), "--split", "dev", "--out", str(root)]) == 0
    scenes = ["synthetic_box-s11", *(f"synthetic_box-s11.{c}" for c in CONDITIONS)]
    assert sorted(p.parent.name for p in root.glob("*/vp000")) == sorted(scenes)
    suite = load(path)
    ideal = read_frame(root / scenes[0] / "vp000")
    for c in CONDITIONS:
        twin = read_frame(root / f"synthetic_box-s11.{c}" / "vp000")
        assert twin.renderer["condition"]["name"] == c
        assert twin.renderer["condition"]["distribution"] == json.loads(json.dumps(suite.conditions[c].to_json()))
        expected = captured_twin(ideal, suite.conditions[c], 11000, c)
        for k in "CUR":
            assert twin.photometric[k] == expected.photometric[k]
            np.testing.assert_array_equal(twin.images[k], expected.images[k])
    assert read_frame(root / "synthetic_box-s11.seams" / "vp000").photometric["R"].seam is not None
    assert len(check_suite_data(suite, "dev", root)) == 7
    # resumable: a rerun derives nothing again
    before = {p: p.stat().st_mtime_ns for p in root.glob("*/vp000/U.png")}
    assert main(["render", "--suite", str(path), "--split", "dev", "--out", str(root)]) == 0
    assert {p: p.stat().st_mtime_ns for p in root.glob("*/vp000/U.png")} == before
    # a held-out condition is reported like any other
    results = evaluate_suite(root, path, "dev", tmp_path / "res", get_methods(["dis-rect:average"]), report=False,
                             ctx=QUIET)
    assert sorted(results["condition"]) == sorted(["ideal", *CONDITIONS])
    # a root derived with another family's settings is refused, naming the twin
    other = tmp_path / "other.toml"
    other.write_text(SUITE.replace('"s-curve-1.5"]', '"s-curve-2"]'))
    with pytest.raises(UserError, match=r"synthetic_box-s11\.tone/vp000.*condition distribution"):
        check_suite_data(load(other), "dev", root)
