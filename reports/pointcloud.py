"""Point clouds from distance maps, and coloured binary PLY files (MeshLab / CloudCompare / Open3D).

PLY layout written here::

    ply
    format binary_little_endian 1.0
    comment tri360 ...
    element vertex N
    property float x
    property float y
    property float z
    property uchar red
    property uchar green
    property uchar blue
    end_header
    <N records of 15 bytes: 3 x float32 LE, 3 x uint8>

Pure: arrays in, bytes out (and back); the report job writes the files.
"""

from __future__ import annotations

import numpy as np

from reconstruction.camera.equirect import bearing_grid

__all__ = ["VERTEX_DTYPE", "point_grid", "ply_bytes", "parse_ply"]

VERTEX_DTYPE = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"),
                         ("red", "u1"), ("green", "u1"), ("blue", "u1")])


def point_grid(distance, position, rotation) -> np.ndarray:
    """World points seen by an equirectangular camera: ``X = position + d * bearing``.

    Args:
        distance: (H, W) distance along each pixel-centre ray, metres; NaN / inf / <= 0 = no point.
        position: (3,) camera centre, metres.
        rotation: (3, 3) world-from-camera rotation.
    Returns:
        (H, W, 3) float64 world coordinates, metres; NaN where there is no point.
    """

    d = np.asarray(distance, dtype=np.float64)
    h, w = d.shape
    d = np.where(np.isfinite(d) & (d > 0), d, np.nan)
    return np.asarray(position, dtype=np.float64) + d[..., None] * bearing_grid(w, h, rotation)


def ply_bytes(points, colors, comment: str = "tri360") -> tuple[bytes, int]:
    """Encode points as a binary little-endian PLY with per-vertex colour.

    Args:
        points: (..., 3) coordinates, metres; rows with any non-finite coordinate are dropped.
        colors: (..., 3) uint8 RGB, same leading shape as ``points``.
        comment: one line of text for the header (no newlines).
    Returns:
        ``(data, n_vertices)``.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    col = np.asarray(colors).reshape(-1, 3)
    if col.shape[0] != pts.shape[0]:
        raise ValueError(f"points and colors differ in count: {pts.shape[0]} vs {col.shape[0]}")
    keep = np.isfinite(pts).all(axis=1)
    pts, col = pts[keep], col[keep]
    verts = np.empty(pts.shape[0], dtype=VERTEX_DTYPE)
    verts["x"], verts["y"], verts["z"] = pts[:, 0], pts[:, 1], pts[:, 2]
    verts["red"], verts["green"], verts["blue"] = col[:, 0], col[:, 1], col[:, 2]
    comment = " ".join(str(comment).split())
    header = ("ply\nformat binary_little_endian 1.0\n"
              f"comment {comment}\n"
              f"element vertex {verts.size}\n"
              "property float x\nproperty float y\nproperty float z\n"
              "property uchar red\nproperty uchar green\nproperty uchar blue\n"
              "end_header\n")
    return header.encode("ascii") + verts.tobytes(), int(verts.size)


def parse_ply(raw: bytes, path: str = "PLY data") -> tuple[np.ndarray, np.ndarray]:
    """Decode a PLY encoded by :func:`ply_bytes` -> ``(points (N, 3) float32, colors (N, 3) uint8)``.

    Args:
        raw: the file's bytes.
        path: what to call the data in error messages (e.g. the file it came from).
    Raises:
        ValueError: if the data is not exactly that layout (naming ``path``).
    """
    end = raw.find(b"end_header\n")
    if not raw.startswith(b"ply\n") or end < 0:
        raise ValueError(f"{path}: not a PLY file (no 'ply' magic or 'end_header')")
    try:
        header = raw[:end].decode("ascii")
    except UnicodeDecodeError:
        raise ValueError(f"{path}: PLY header is not ASCII text") from None
    lines = [ln.strip() for ln in header.splitlines() if not ln.startswith("comment")]
    if len(lines) < 3:
        raise ValueError(f"{path}: PLY header too short ({len(lines)} lines)")
    expected_props = ["property float x", "property float y", "property float z",
                      "property uchar red", "property uchar green", "property uchar blue"]
    if lines[1] != "format binary_little_endian 1.0":
        raise ValueError(f"{path}: unexpected format line {lines[1]!r}")
    if not lines[2].startswith("element vertex ") or lines[3:] != expected_props:
        raise ValueError(f"{path}: unexpected header {lines[2:]}")
    n = int(lines[2].split()[2])
    body = raw[end + len(b"end_header\n"):]
    if len(body) != n * VERTEX_DTYPE.itemsize:
        raise ValueError(f"{path}: {len(body)} bytes of vertex data, expected {n * VERTEX_DTYPE.itemsize}")
    verts = np.frombuffer(body, dtype=VERTEX_DTYPE)
    pts = np.stack([verts["x"], verts["y"], verts["z"]], axis=1)
    col = np.stack([verts["red"], verts["green"], verts["blue"]], axis=1)
    return pts, col
