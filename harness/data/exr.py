"""OpenEXR files: one reader for every part and channel, and single-channel float32 maps.

- :func:`read_exr_channels` -> ``{channel name: (H, W) array}`` merged over every part (Blender 5.0 writes
  multi-layer EXRs as multi-part files: Combined in part 0, Depth in part 1, ...; ``OpenEXR.File.channels()``
  alone only sees part 0).
- :func:`read_float_map` / :func:`write_float_map`: one float32 channel with a given name (``"distance"``,
  ``"confidence"``); :func:`float_channel` picks one out of an already-read dict.
- :func:`read_distance_exr` / :func:`write_distance_exr`: the distance maps of the frame format (metres,
  +inf = no surface; Cycles' 1e10 "no hit" becomes +inf); :func:`distance_map` applies those conventions to
  a channel already read (one read of a Blender file gives both the colour and the depth).

Damaged files.  OpenEXR 3.5.3's Python binding does *not* raise for a file whose header is intact but whose
pixel data is truncated or corrupt: the C core prints ``(EXR_ERR_BAD_CHUNK_LEADER) ...`` to descriptor 2, the
binding prints ``Warning: Exception raised reading pixel data for part 0 - ...`` to descriptor 1, and
``OpenEXR.File(...).parts`` comes back *empty* -- which used to surface as "no channel named 'distance' (found
[])".  So before decoding, :func:`check_exr_structure` reads the headers and the chunk offset tables itself
and checks that every chunk lies inside the file (what truncation and most overwrites break); the decode then
runs with the library's output captured (:mod:`harness.data.native`), and any part or header channel that did
not come back is reported.  Both cases give one :class:`FrameError` "truncated or corrupt OpenEXR file" naming
the file.  What cannot be detected: EXR has no checksums, so overwritten bytes inside *uncompressed* pixel
data decode to different, plausible numbers (the distance checks catch NaN and non-positive values only).
"""

from __future__ import annotations

import math
import os
import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import OpenEXR

from harness.data.atomic import atomic_write_via
from harness.data.errors import FrameError
from harness.data.native import first_library_message, native_output_captured

__all__ = [
    "DISTANCE_CHANNEL",
    "CONFIDENCE_CHANNEL",
    "NO_HIT_THRESHOLD_M",
    "ExrPart",
    "check_exr_structure",
    "read_exr_channels",
    "write_exr_channels",
    "float_channel",
    "read_float_map",
    "write_float_map",
    "distance_map",
    "read_distance_exr",
    "write_distance_exr",
]

DISTANCE_CHANNEL = "distance"
CONFIDENCE_CHANNEL = "confidence"
NO_HIT_THRESHOLD_M = 1e9  # Cycles writes 1e10 for rays that hit nothing; anything above is stored as +inf

_MAGIC = 20000630
_TILED_FLAG, _LONG_NAMES_FLAG, _NON_IMAGE_FLAG, _MULTIPART_FLAG = 0x200, 0x400, 0x800, 0x1000
#: scan lines per chunk, by compression id (openexr_compression.h); ids not listed are not chunk-checked
_LINES_PER_CHUNK = {0: 1, 1: 1, 2: 1, 3: 16, 4: 32, 5: 16, 6: 32, 7: 32, 8: 32, 9: 256, 10: 256, 11: 32}
_MAX_HEADER_BYTES = 64 << 20  # a header larger than this is treated as corrupt


class _Damaged(Exception):
    """Internal: the structure check found damage (message says what)."""


@dataclass
class ExrPart:
    """What :func:`check_exr_structure` learned about one part of an EXR file.

    Attributes:
        channels: channel names listed in the part's header.
        width, height: data window size, pixels.
        storage: "scanline", "tiled", "deepscanline" or "deeptile".
        chunks: number of chunks in the offset table; None where it could not be determined (then the chunk
            table of this part and of the parts after it is not checked).
    """

    channels: list[str] = field(default_factory=list)
    width: int = 0
    height: int = 0
    storage: str = "scanline"
    chunks: int | None = None


class _Reader:
    """Bounds-checked sequential reads from an open binary file of known size."""

    def __init__(self, fh, size: int):
        self.fh, self.size = fh, size

    @property
    def pos(self) -> int:
        return self.fh.tell()

    def read(self, n: int, what: str) -> bytes:
        if n < 0 or self.pos + n > self.size:
            raise _Damaged(f"the file ends inside the {what} (byte {self.pos} + {n} > {self.size} bytes)")
        data = self.fh.read(n)
        if len(data) != n:
            raise _Damaged(f"the file ends inside the {what}")
        return data

    def cstring(self, what: str, limit: int = 256) -> str:
        out = bytearray()
        while True:
            b = self.read(1, what)
            if b == b"\0":
                return out.decode("latin-1")
            out += b
            if len(out) > limit:
                raise _Damaged(f"{what} is not terminated within {limit} bytes")


def _parse_header(r: _Reader, long_names: bool) -> dict[str, tuple[str, bytes]] | None:
    """One header -> {attribute name: (type, raw value)}; None for the empty header ending a multi-part list."""
    attrs: dict[str, tuple[str, bytes]] = {}
    start = r.pos
    limit = 255 if long_names else 31
    while True:
        name = r.cstring("header", limit=limit)
        if not name:
            return attrs or None
        typ = r.cstring(f"type of header attribute {name!r}", limit=limit)
        (size,) = struct.unpack("<i", r.read(4, f"size of header attribute {name!r}"))
        if size < 0:
            raise _Damaged(f"header attribute {name!r} has a negative size")
        attrs[name] = (typ, r.read(size, f"header attribute {name!r}"))
        if r.pos - start > _MAX_HEADER_BYTES:
            raise _Damaged("the header is implausibly large")


def _channel_names(raw: bytes) -> list[str]:
    names, i = [], 0
    while i < len(raw) and raw[i] != 0:
        end = raw.index(b"\0", i) if b"\0" in raw[i:] else -1
        if end < 0:
            raise _Damaged("the channel list is malformed")
        names.append(raw[i:end].decode("latin-1"))
        i = end + 1 + 16  # pixel type (4), pLinear + reserved (4), x/y sampling (8)
    return names


def _level_count(size: int, rounding: int) -> int:
    """Number of mip levels of a ``size``-pixel axis: floor/ceil(log2(size)) + 1 (rounding 0 = down)."""
    if size <= 1:
        return 1
    lg = math.floor(math.log2(size)) if rounding == 0 else math.ceil(math.log2(size))
    return lg + 1


def _level_size(size: int, level: int, rounding: int) -> int:
    s = size / (1 << level)
    return max(1, math.floor(s) if rounding == 0 else math.ceil(s))


def _tile_chunks(w: int, h: int, raw: bytes) -> int | None:
    if len(raw) != 9:
        raise _Damaged("the 'tiles' attribute is malformed")
    tx, ty, mode = struct.unpack("<IIB", raw)
    if tx < 1 or ty < 1:
        raise _Damaged("the tile size is zero")
    level_mode, rounding = mode & 0x0F, mode >> 4

    def n_tiles(lw, lh):
        return -(-lw // tx) * -(-lh // ty)

    if level_mode == 0:
        return n_tiles(w, h)
    if level_mode == 1:
        n = _level_count(max(w, h), rounding)
        return sum(n_tiles(_level_size(w, lv, rounding), _level_size(h, lv, rounding)) for lv in range(n))
    if level_mode == 2:
        nx, ny = _level_count(w, rounding), _level_count(h, rounding)
        return sum(n_tiles(_level_size(w, lx, rounding), _level_size(h, ly, rounding))
                   for lx in range(nx) for ly in range(ny))
    return None


def _describe_part(attrs: dict[str, tuple[str, bytes]], single_tiled: bool, deep_flag: bool) -> ExrPart:
    part = ExrPart()
    if "channels" not in attrs or "dataWindow" not in attrs:
        raise _Damaged("a header lacks the required 'channels' or 'dataWindow' attribute")
    part.channels = _channel_names(attrs["channels"][1])
    raw = attrs["dataWindow"][1]
    if len(raw) != 16:
        raise _Damaged("the 'dataWindow' attribute is malformed")
    x0, y0, x1, y1 = struct.unpack("<4i", raw)
    part.width, part.height = x1 - x0 + 1, y1 - y0 + 1
    if part.width < 1 or part.height < 1:
        raise _Damaged(f"the data window is empty ({part.width}x{part.height})")
    if "type" in attrs:
        part.storage = attrs["type"][1].rstrip(b"\0").decode("latin-1")
    elif single_tiled:
        part.storage = "tiledimage"
    elif deep_flag:
        part.storage = "deepscanline"
    part.storage = {"scanlineimage": "scanline", "tiledimage": "tiled"}.get(part.storage, part.storage)
    if "chunkCount" in attrs:
        raw = attrs["chunkCount"][1]
        if len(raw) != 4 or struct.unpack("<i", raw)[0] < 0:
            raise _Damaged("the 'chunkCount' attribute is malformed")
        (part.chunks,) = struct.unpack("<i", raw)
    elif part.storage == "scanline" and len(attrs.get("compression", ("", b""))[1]) == 1:
        lines = _LINES_PER_CHUNK.get(attrs["compression"][1][0])
        part.chunks = None if lines is None else -(-part.height // lines)
    elif part.storage == "tiled" and "tiles" in attrs:
        part.chunks = _tile_chunks(part.width, part.height, attrs["tiles"][1])
    return part


def _leader_size(storage: str, multipart: bool) -> tuple[int, str]:
    """(bytes of a chunk's leader, struct format of its size fields) for a storage type."""
    base = 4 if multipart else 0
    if storage == "scanline":
        return base + 8, "<i"  # y, packed size
    if storage == "tiled":
        return base + 20, "<i"  # tile x, y, level x, y, packed size
    if storage == "deepscanline":
        return base + 28, "<qq"  # y, packed offset table size, packed sample size, (unpacked size)
    if storage == "deeptile":
        return base + 40, "<qq"
    raise _Damaged(f"unknown part type {storage!r}")


def _check_chunks(r: _Reader, parts: list[ExrPart], multipart: bool) -> None:
    tables = []
    for part in parts:
        if part.chunks is None:
            break  # cannot locate the following tables either
        raw = r.read(8 * part.chunks, "chunk offset table")
        tables.append(struct.unpack(f"<{part.chunks}Q", raw))
    table_end = r.pos
    for index, (part, offsets) in enumerate(zip(parts, tables, strict=False)):
        lead, size_fmt = _leader_size(part.storage, multipart)
        where = f"part {index}, " if multipart else ""
        for k, off in enumerate(offsets):
            chunk = f"{where}chunk {k + 1} of {len(offsets)}"
            if off == 0:
                raise _Damaged(f"{chunk} was never written (offset 0)")
            if off < table_end or off + lead > r.size:
                raise _Damaged(f"{chunk} starts at byte {off}, outside the file's data ({table_end}..{r.size})")
            r.fh.seek(off)
            leader = r.read(lead, f"leader of {chunk}")
            if multipart and struct.unpack("<i", leader[:4])[0] != index:
                raise _Damaged(f"{chunk} belongs to another part")
            if size_fmt == "<i":
                packed = struct.unpack("<i", leader[-4:])[0]
            else:  # deep: packed offset table + packed sample data follow the leader
                packed = sum(struct.unpack("<qq", leader[-24:-8]))
            if packed < 0 or off + lead + packed > r.size:
                raise _Damaged(f"{chunk} ends at byte {off + lead + packed}, but the file has {r.size} bytes")


def check_exr_structure(path: Path) -> list[ExrPart]:
    """Read the headers and chunk tables of an EXR file and check that every chunk lies inside the file.

    Pure Python, reads only the headers, the offset tables and one small leader per chunk (no pixel data).

    Returns:
        One :class:`ExrPart` per part.
    Raises:
        FrameError: "not a readable OpenEXR file" (bad magic number or version) or "truncated or corrupt OpenEXR file
            (<what>)", naming ``path``.
    """
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            size = os.fstat(fh.fileno()).st_size
            head = fh.read(8)
            if len(head) < 8 or struct.unpack("<i", head[:4])[0] != _MAGIC:
                raise FrameError(f"{path}: not a readable OpenEXR file (no EXR magic number)")
            (version,) = struct.unpack("<i", head[4:])
            if version & 0xFF != 2:
                raise FrameError(f"{path}: not a readable OpenEXR file (format version {version & 0xFF})")
            multipart = bool(version & _MULTIPART_FLAG)
            r = _Reader(fh, size)
            try:
                headers = []
                while True:
                    attrs = _parse_header(r, bool(version & _LONG_NAMES_FLAG))
                    if attrs is None:
                        break
                    headers.append(attrs)
                    if not multipart:
                        break
                if not headers:
                    raise _Damaged("no header")
                parts = [_describe_part(a, bool(version & _TILED_FLAG), bool(version & _NON_IMAGE_FLAG))
                         for a in headers]
                _check_chunks(r, parts, multipart)
            except (_Damaged, struct.error, ValueError, IndexError, OverflowError) as exc:
                raise FrameError(f"{path}: truncated or corrupt OpenEXR file ({exc})") from None
    except IsADirectoryError:
        raise FrameError(f"{path}: is a directory, not an OpenEXR file") from None
    except FileNotFoundError:
        raise FrameError(f"{path}: file is missing") from None
    except OSError as exc:
        raise FrameError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    return parts


def read_exr_channels(path: Path) -> dict[str, np.ndarray]:
    """Every channel of every part of an EXR file.

    Returns:
        ``{channel name: (H, W) array}`` in the stored pixel type (float16, float32 or uint32), merged over
        all parts (channel names as stored, e.g. ``"ViewLayer.Depth.Z"`` in a Blender multi-part file).
    Raises:
        FrameError: naming ``path``: missing, not an EXR file, "truncated or corrupt" (header intact but
            pixel data cut off or undecodable), or a channel name that appears in two parts.
    """
    path = Path(path)
    if not path.exists():
        raise FrameError(f"{path}: file is missing")
    parts = check_exr_structure(path)
    with native_output_captured() as captured:
        try:
            # separate_channels: one (H, W) array per channel, not R/G/B grouped into (H, W, 3)
            read = OpenEXR.File(str(path), separate_channels=True).parts
            error = None
        except Exception as exc:  # the binding raises bare RuntimeError/Exception on unreadable input
            read, error = [], exc
    if error is not None:
        why = first_library_message(captured.text, path) or str(error)
        raise FrameError(f"{path}: truncated or corrupt OpenEXR file ({why})") from None
    channels: dict[str, np.ndarray] = {}
    missing = []
    for index, expected in enumerate(parts):
        got = read[index].channels if index < len(read) else {}
        missing += [c for c in expected.channels if c not in got]
        for name, ch in got.items():
            if name in channels:
                raise FrameError(f"{path}: channel {name!r} appears in more than one part")
            channels[name] = np.asarray(ch.pixels)
    if missing or len(read) != len(parts):
        why = first_library_message(captured.text, path) or f"channels {missing} could not be decoded"
        raise FrameError(f"{path}: truncated or corrupt OpenEXR file (pixel data could not be decoded: {why})")
    captured.release()
    return channels


def write_exr_channels(path: Path, channels: dict[str, np.ndarray]) -> None:
    """Write ``{name: (H, W) array}`` (float16, float32 or uint32) as one ZIP-compressed scan-line EXR part,
    atomically (mode ``0o666 & ~umask``)."""
    arrays = {name: np.ascontiguousarray(a) for name, a in channels.items()}
    shapes = {a.shape for a in arrays.values()}
    if not arrays or len(shapes) != 1 or len(next(iter(shapes))) != 2:
        raise FrameError(f"{path}: channels must be (H, W) arrays of one size, got {sorted(shapes)}")
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}

    def writer(tmp: str) -> None:
        OpenEXR.File(header, arrays).write(tmp)

    atomic_write_via(path, writer)


def float_channel(channels: dict[str, np.ndarray], path: Path, channel: str) -> np.ndarray:
    """Pick one channel out of :func:`read_exr_channels`' result -> (H, W) float32 (half floats are widened).

    Raises:
        FrameError: naming ``path``: no channel of that name (listing those found), or not a numeric map.
    """
    if channel not in channels:
        raise FrameError(f"{path}: no channel named {channel!r} (found {sorted(channels)})")
    values = channels[channel]
    if values.ndim != 2:
        raise FrameError(f"{path}: channel {channel!r} must be single-valued (H, W), got shape {values.shape}")
    if values.dtype.kind != "f":
        raise FrameError(f"{path}: channel {channel!r} must be floating point, got {values.dtype}")
    return values.astype(np.float32, copy=False)


def read_float_map(path: Path, channel: str) -> np.ndarray:
    """Read one channel of an EXR file -> (H, W) float32 (:func:`read_exr_channels` + :func:`float_channel`)."""
    return float_channel(read_exr_channels(path), path, channel)


def write_float_map(path: Path, values: np.ndarray, channel: str) -> None:
    """Write an (H, W) map as a float32 EXR with one channel named ``channel``, atomically."""
    v = np.ascontiguousarray(values, dtype=np.float32)
    if v.ndim != 2:
        raise FrameError(f"{path}: {channel} map must be 2-D (H, W), got shape {v.shape}")
    write_exr_channels(path, {channel: v})


def write_distance_exr(path: Path, distance: np.ndarray) -> None:
    """Write an (H, W) distance map (metres, +inf = no surface) as a float32 EXR, channel "distance".

    Raises:
        FrameError: not 2-D, or contains NaN.
    """
    d = np.asarray(distance, dtype=np.float32)
    if d.ndim != 2:
        raise FrameError(f"{path}: distance map must be 2-D (H, W), got shape {d.shape}")
    if np.isnan(d).any():
        raise FrameError(f"{path}: distance map contains NaN")
    write_float_map(path, d, DISTANCE_CHANNEL)


def distance_map(values: np.ndarray, path: Path, channel: str = DISTANCE_CHANNEL) -> np.ndarray:
    """Apply the distance conventions to a raw (H, W) channel read from ``path``: values above 1e9 m (Cycles'
    "no hit") become +inf; NaN, -inf and values <= 0 are refused.

    Returns:
        (H, W) float32 metres, +inf = no surface.
    Raises:
        FrameError: naming ``path`` and ``channel``.
    """
    d = np.asarray(values, dtype=np.float32)
    if np.isnan(d).any():
        raise FrameError(f"{path}: channel {channel!r} contains NaN")
    d = np.where(d > NO_HIT_THRESHOLD_M, np.float32(np.inf), d)
    if (d <= 0).any():
        raise FrameError(f"{path}: distances must be positive (found min {float(d.min()):.4g} m)")
    return d


def read_distance_exr(path: Path, channel: str = DISTANCE_CHANNEL) -> np.ndarray:
    """Read a distance EXR -> (H, W) float32 metres, +inf = no surface (:func:`distance_map` conventions).

    Raises:
        FrameError: naming ``path``: see :func:`read_exr_channels`, :func:`float_channel`, :func:`distance_map`.
    """
    return distance_map(read_float_map(path, channel), path, channel)
