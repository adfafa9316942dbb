"""An outside method for tri360, written like third-party code: numpy, OpenCV and OpenEXR only, no tri360 import.

It reads only the frame files anyone gets (C.png, U.png, R.png, frame.json; never a *.distance.exr) and
estimates camera C's distance from the vertical pair C-U alone: U sits straight above C, so a surface point
keeps its longitude and only moves down in U's image.  DIS optical flow C->U gives that shift dv (pixels);
with C's latitude phi_C and U's phi_U = phi_C - pi dv / H the triangle C-U-X gives (law of sines)

    distance = baseline * cos(phi_U) / sin(phi_C - phi_U)   metres.

Confidence (higher = better): the forward-backward consistency of the flow times cos(phi_C) (the pair's
epipoles are the poles, where the triangle degenerates).  Pixels with a shift below 0.2 px get no prediction.

    python examples/outside_method.py DATA_ROOT PRED_ROOT

writes PRED_ROOT/<scene>/<viewpoint>/{distance,confidence}.exr and PRED_ROOT/method.json (format tri360-pred/1).
"""

import json
import sys
from pathlib import Path

import cv2
import numpy as np
import OpenEXR

MIN_SHIFT_PX = 0.2  # smaller vertical shifts are too close to "infinitely far" to triangulate
AXIS_TOL = 1e-3  # the C->U baseline must be C's +Z axis within this (unit vector difference)


def write_exr(path: Path, channel: str, values: np.ndarray) -> None:
    """One float32 channel, ZIP compressed."""
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    OpenEXR.File(header, {channel: np.ascontiguousarray(values, dtype=np.float32)}).write(str(path))


def grey(path: Path) -> np.ndarray:
    img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if img is None:
        sys.exit(f"{path}: cannot be read")
    return img


def estimate(frame_dir: Path, meta: dict) -> tuple[np.ndarray, np.ndarray]:
    """C's distance (H, W) float32 metres (NaN = no prediction) and confidence (H, W) float32 in [0, 1]."""
    cams = meta["cameras"]
    rot_c = np.asarray(cams["C"]["rotation"], dtype=np.float64)  # world-from-camera
    t = rot_c.T @ (np.asarray(cams["U"]["position"]) - np.asarray(cams["C"]["position"]))
    baseline = float(np.linalg.norm(t))
    if np.abs(t / baseline - [0.0, 0.0, 1.0]).max() > AXIS_TOL:
        sys.exit(f"{frame_dir}: this example needs U straight above C (C->U = {t} in C's camera frame)")
    c, u = grey(frame_dir / "C.png"), grey(frame_dir / "U.png")
    h, w = c.shape
    dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)
    fwd = dis.calc(c, u, None)  # (H, W, 2): C pixel (x, y) matches U pixel (x + fx, y + fy)
    bwd = dis.calc(u, c, None)
    xs, ys = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    back = cv2.remap(bwd, xs + fwd[..., 0], ys + fwd[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    fb_err = np.linalg.norm(fwd + back, axis=2)  # pixels; 0 for a consistent match
    phi_c = np.pi / 2 - np.pi * (ys + 0.5) / h
    shift = fwd[..., 1].astype(np.float64)
    phi_u = phi_c - np.pi * shift / h
    with np.errstate(divide="ignore", invalid="ignore"):
        distance = baseline * np.cos(phi_u) / np.sin(phi_c - phi_u)
    distance[(shift < MIN_SHIFT_PX) | ~np.isfinite(distance) | (distance <= 0)] = np.nan
    confidence = np.cos(phi_c) * np.exp(-fb_err)
    return distance.astype(np.float32), confidence.astype(np.float32)


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print("usage: python examples/outside_method.py DATA_ROOT PRED_ROOT", file=sys.stderr)
        return 2
    data_root, pred_root = Path(argv[0]), Path(argv[1])
    frames = sorted(p.parent for p in data_root.rglob("frame.json"))
    if not frames:
        sys.exit(f"{data_root}: no frame.json found")
    for frame_dir in frames:
        meta = json.loads((frame_dir / "frame.json").read_text(encoding="utf-8"))
        distance, confidence = estimate(frame_dir, meta)
        out = pred_root / meta["scene"] / meta["viewpoint"]
        out.mkdir(parents=True, exist_ok=True)
        write_exr(out / "distance.exr", "distance", distance)
        write_exr(out / "confidence.exr", "confidence", confidence)
        share = float(np.isfinite(distance).mean())
        print(f"{meta['scene']}/{meta['viewpoint']}: {100 * share:.1f} % of the pixels predicted -> {out}")
    info = {"format": "tri360-pred/1", "name": "dis-vertical",
            "description": "DIS optical flow on the vertical pair C-U only, law-of-sines triangulation",
            "url": "examples/outside_method.py",
            "parameters": {"preset": "DISOPTICAL_FLOW_PRESET_MEDIUM", "min_shift_px": MIN_SHIFT_PX}}
    pred_root.mkdir(parents=True, exist_ok=True)
    (pred_root / "method.json").write_text(json.dumps(info, indent=2) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
