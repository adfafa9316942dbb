"""8-bit PNG images of the frame format: (H, W, 3) uint8 RGB in memory, written atomically.

libpng reports a damaged file by printing ``libpng error: ...`` to file descriptor 2 and OpenCV returns
``None``; the decode therefore runs with native output captured (:mod:`harness.data.native`) and a failure
becomes one :class:`FrameError` naming the file (quoting libpng's reason).  libjpeg decodes a damaged JPEG
anyway, printing ``Corrupt JPEG data: ...`` or ``Premature end of JPEG file``: a JPEG whose decode printed
anything, or that has no end-of-image marker, is refused the same way.  The size a PNG or JPEG header claims is
checked before decoding (at most :data:`MAX_IMAGE_SIDE` pixels a side and :data:`MAX_IMAGE_PIXELS` in all), so a
small file claiming a huge image is one line, not an allocation failure.
"""

from __future__ import annotations

import re
from pathlib import Path

import cv2
import numpy as np

from harness.data.atomic import atomic_write_bytes
from harness.data.errors import FrameError
from harness.data.native import first_library_message, native_output_captured

__all__ = ["PNG_SIGNATURE", "JPEG_SIGNATURE", "MAX_IMAGE_SIDE", "MAX_IMAGE_PIXELS", "header_size", "require_file",
           "read_png", "write_png"]

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
JPEG_SIGNATURE = b"\xff\xd8"
MAX_IMAGE_SIDE = 32768
"""The widest (or tallest) image tri360 reads, pixels."""
MAX_IMAGE_PIXELS = 1 << 28
"""The most pixels tri360 reads in one image (268 M: 3 x 256 MiB decoded; a 23170 x 11585 equirect)."""
#: what libjpeg prints about a damaged file it decodes anyway ("Corrupt JPEG data: ...", "Premature end of JPEG file")
_LIBJPEG_COMPLAINT = re.compile(r"JPEG|Corrupt|Premature|Invalid|Bogus")
#: JPEG start-of-frame markers (SOF0-SOF15 without DHT C4, JPG C8 and DAC CC): their segment holds the size
_JPEG_SOF = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}


def header_size(raw: bytes) -> tuple[int, int] | None:
    """``(width, height)`` that a PNG (IHDR) or JPEG (start-of-frame segment) header claims, or None for other
    formats and headers too short or malformed to say."""
    if raw[:8] == PNG_SIGNATURE:
        if len(raw) < 24 or raw[12:16] != b"IHDR":
            return None
        return int.from_bytes(raw[16:20], "big"), int.from_bytes(raw[20:24], "big")
    if raw[:2] == JPEG_SIGNATURE:
        i = 2
        while i + 4 <= len(raw):
            if raw[i] != 0xFF:
                return None
            marker = raw[i + 1]
            if marker == 0xFF:  # fill byte
                i += 1
                continue
            if marker in (0x01, *range(0xD0, 0xD8)):  # markers without a segment
                i += 2
                continue
            length = int.from_bytes(raw[i + 2:i + 4], "big")
            if marker in _JPEG_SOF:
                if i + 9 > len(raw):
                    return None
                return int.from_bytes(raw[i + 7:i + 9], "big"), int.from_bytes(raw[i + 5:i + 7], "big")
            if marker == 0xDA or length < 2:  # start of scan before any frame header
                return None
            i += 2 + length
    return None


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


def require_file(path: Path) -> None:
    """Refuse a ``path`` that is not there or not a regular file, as :func:`read_png` does (without opening it).

    Raises:
        FrameError: naming ``path``: "file is missing" or "is not a regular file".
    """
    path = Path(path)
    if not path.exists():
        raise FrameError(f"{path}: file is missing")
    if not path.is_file():
        raise FrameError(f"{path}: is not a regular file")


def read_png(path: Path) -> np.ndarray:
    """Read an 8-bit image (PNG; anything OpenCV decodes is accepted) -> (H, W, 3) uint8 RGB.

    Grey images are repeated to three channels; an alpha channel is dropped.

    Raises:
        FrameError: naming ``path``: missing, a directory, empty, a header claiming more than
            :data:`MAX_IMAGE_SIDE` / :data:`MAX_IMAGE_PIXELS`, "truncated or corrupt PNG file" (a PNG signature but
            undecodable data), "truncated or corrupt JPEG file" (libjpeg complained, or no end-of-image marker),
            not an image at all, or not 8-bit.
    """
    path = Path(path)
    require_file(path)
    try:
        raw = np.fromfile(str(path), dtype=np.uint8)
    except OSError as exc:
        raise FrameError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    if raw.size == 0:
        raise FrameError(f"{path}: file is empty (not a readable image)")
    head = raw[:1 << 16].tobytes()
    size = header_size(head)
    if size is not None and (max(size) > MAX_IMAGE_SIDE or size[0] * size[1] > MAX_IMAGE_PIXELS or min(size) < 1):
        raise FrameError(f"{path}: header claims a {size[0]}x{size[1]} image; tri360 reads images of 1 to "
                         f"{MAX_IMAGE_SIDE} pixels a side and at most {MAX_IMAGE_PIXELS} pixels")
    is_jpeg = head[:2] == JPEG_SIGNATURE
    with native_output_captured() as captured:
        try:
            img = cv2.imdecode(raw, cv2.IMREAD_UNCHANGED)
        except cv2.error as exc:  # e.g. OpenCV's own size limit in a format without a header we parse
            img, reason = None, str(exc).strip().splitlines()[-1] if str(exc).strip() else "OpenCV error"
        else:
            reason = ""
    why = first_library_message(captured.text, path) or reason
    if img is None:
        if head[: len(PNG_SIGNATURE)] == PNG_SIGNATURE:
            raise FrameError(f"{path}: truncated or corrupt PNG file" + (f" ({why})" if why else ""))
        if is_jpeg:
            raise FrameError(f"{path}: truncated or corrupt JPEG file" + (f" ({why})" if why else ""))
        raise FrameError(f"{path}: not a readable image (no PNG signature, and no other format OpenCV reads)"
                         + (f" ({why})" if why else ""))
    if is_jpeg and (_LIBJPEG_COMPLAINT.search(captured.text) or b"\xff\xd9" not in raw.tobytes()):
        raise FrameError(f"{path}: truncated or corrupt JPEG file ("
                         + (why or "no end-of-image marker") + ")")
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
