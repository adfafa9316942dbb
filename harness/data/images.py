"""8-bit PNG images of the frame format: (H, W, 3) uint8 RGB in memory, written atomically.

libpng reports a damaged file by printing ``libpng error: ...`` to file descriptor 2 and OpenCV returns
``None``; the decode therefore runs with native output captured (:mod:`harness.data.native`) and a failure
becomes one :class:`FrameError` naming the file (quoting libpng's reason).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from harness.data.atomic import atomic_write_bytes
from harness.data.errors import FrameError
from harness.data.native import first_library_message, native_output_captured

__all__ = ["PNG_SIGNATURE", "read_png", "write_png"]

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def write_png(path: Path, image: np.ndarray) -> None:
    """Write an (H, W, 3) uint8 RGB image as an 8-bit PNG, atomically (mode ``0o666 & ~umask``).

    Raises:
        FrameError: the array is not (H, W, 3) uint8 with H, W >= 1, or encoding failed.
    """
    img = np.asarray(image)
    if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] != 3 or min(img.shape[:2]) < 1:
        raise FrameError(f"{path}: image must be (H, W, 3) uint8, got {img.shape} {img.dtype}")
    ok, buf = cv2.imencode(".png", cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
    if not ok:
        raise FrameError(f"{path}: PNG encoding failed")
    atomic_write_bytes(path, buf.tobytes())


def read_png(path: Path) -> np.ndarray:
    """Read an 8-bit image (PNG; anything OpenCV decodes is accepted) -> (H, W, 3) uint8 RGB.

    Grey images are repeated to three channels; an alpha channel is dropped.

    Raises:
        FrameError: naming ``path``: missing, a directory, empty, "truncated or corrupt PNG file" (a PNG
            signature but undecodable data), not an image at all, or not 8-bit.
    """
    path = Path(path)
    if not path.exists():
        raise FrameError(f"{path}: file is missing")
    if not path.is_file():
        raise FrameError(f"{path}: is not a regular file")
    try:
        raw = np.fromfile(str(path), dtype=np.uint8)
    except OSError as exc:
        raise FrameError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    if raw.size == 0:
        raise FrameError(f"{path}: file is empty (not a readable image)")
    with native_output_captured() as captured:
        img = cv2.imdecode(raw, cv2.IMREAD_UNCHANGED)
    if img is None:
        why = first_library_message(captured.text, path)
        if raw[: len(PNG_SIGNATURE)].tobytes() == PNG_SIGNATURE:
            raise FrameError(f"{path}: truncated or corrupt PNG file" + (f" ({why})" if why else ""))
        raise FrameError(f"{path}: not a readable image (no PNG signature, and no other format OpenCV reads)")
    captured.release()
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
