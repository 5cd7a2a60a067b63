"""Frame sources: lazily read image files or a video, decode each frame once.

An image-file source reads the file's bytes, decodes them (JPEG with libjpeg-turbo through
simplejpeg, the rest with ``cv2.imdecode``) and hands both on, so the Rerun sink can pass
JPEG/PNG bytes through without re-encoding.
Nothing is cached: a 10 000-frame sequence holds only its list of file names.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import simplejpeg

from pipeline.errors import InputError
from pipeline.libmsg import library_says

IMAGE_EXTENSIONS = (".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff", ".pgm", ".ppm", ".webp")
VIDEO_EXTENSIONS = (".mp4", ".avi", ".mov", ".mkv", ".mpg", ".mpeg", ".wmv", ".m4v", ".webm")
_MEDIA_TYPES = {".jpg": "image/jpeg", ".jpeg": "image/jpeg", ".png": "image/png"}


@dataclass(frozen=True, slots=True)
class EncodedFrame:
    """The source bytes of a frame and their media type (``image/jpeg`` or ``image/png``)."""

    data: bytes
    media_type: str


@dataclass(frozen=True, slots=True)
class RawFrame:
    """One decoded frame: the array as stored (uint8/uint16, 1 or 3 channels) and its bytes."""

    image: np.ndarray
    encoded: EncodedFrame | None


def natural_key(name: str) -> list[object]:
    """Sort key that orders ``frame2`` before ``frame10``."""
    return [int(t) if t.isdigit() else t.lower() for t in re.split(r"(\d+)", name)]


def list_images(folder: Path) -> list[Path]:
    """Image files directly inside ``folder``, in natural sorted order.

    Raises
    ------
    InputError
        When an entry named like a frame (an image extension) is not a readable file: a
        folder, a broken symbolic link, a FIFO or device (reading one would block). Skipping
        it would shift every later frame against the other channel and the truth.
    """
    named = sorted(
        (p for p in folder.iterdir() if p.suffix.lower() in IMAGE_EXTENSIONS),
        key=lambda p: natural_key(p.name),
    )
    for i, p in enumerate(named):
        if not p.is_file():
            raise InputError(f"frame {i + 1}: {p} is {_what_it_is(p)}, not an image file")
    return named


def _what_it_is(path: Path) -> str:
    if path.is_symlink() and not path.exists():
        return f"a broken symbolic link (to {os.readlink(path)})"
    if path.is_dir():
        return "a folder"
    if path.is_fifo():
        return "a FIFO"
    if path.is_socket():
        return "a socket"
    if path.is_char_device() or path.is_block_device():
        return "a device"
    return "not a regular file"


class ImageListSource:
    """Frames stored as one image file each.

    ``grey`` (set for an infrared channel) decodes JPEG files straight to their luminance:
    a thermal JPEG stored as three equal channels costs a third less to decode that way,
    and the trackers see the same grey levels. Other formats are read as stored (16-bit
    PNG/TIFF stay 16-bit).
    """

    def __init__(self, paths: list[Path], grey: bool = False):
        self.paths = paths
        self.grey = grey
        self.scale = 1
        """JPEG files are decoded at ``1 / scale`` of their size (libjpeg's DCT scaling: 1, 2, 4
        or 8); other formats are read whole (:class:`pipeline.io.sequence.Sequence` resizes
        them)."""

    def __len__(self) -> int:
        return len(self.paths)

    @property
    def description(self) -> str:
        return f"{self.paths[0].parent}" if self.paths else "(no frames)"

    def read(self, index0: int) -> RawFrame:
        """Decode frame ``index0`` (0-based). Raises InputError when it cannot be read."""
        path = self.paths[index0]
        try:
            data = path.read_bytes()
        except OSError as exc:
            raise InputError(f"cannot read frame {index0 + 1}: {path}: {exc.strerror}") from None
        if not data:
            raise InputError(f"unreadable frame {index0 + 1}: {path} is empty (0 bytes)")
        jpeg = path.suffix.lower() in (".jpg", ".jpeg")
        image = _decode_jpeg(data, self.grey, self.scale) if jpeg else None
        if image is None:
            flag = cv2.IMREAD_GRAYSCALE if self.grey and jpeg else cv2.IMREAD_UNCHANGED
            try:
                image = cv2.imdecode(np.frombuffer(data, np.uint8), flag)
            except cv2.error:
                image = None
        if image is None or image.size == 0:
            raise InputError(
                f"unreadable frame {index0 + 1}: {path} is not a decodable image{library_says()}"
            )
        if image.ndim == 3 and image.shape[2] == 4:
            image = cv2.cvtColor(image, cv2.COLOR_BGRA2BGR)
        media = _MEDIA_TYPES.get(path.suffix.lower())
        if media is not None and image.dtype != np.uint8:
            media = None  # 16-bit PNG: the viewer gets the normalized 8-bit frame instead
        return RawFrame(image, EncodedFrame(data, media) if media else None)

    def iterate(self, start0: int = 0) -> Iterator[RawFrame]:
        for i in range(start0, len(self.paths)):
            yield self.read(i)


def _decode_jpeg(data: bytes, grey: bool, scale: int = 1) -> np.ndarray | None:
    """A JPEG decoded by libjpeg-turbo through simplejpeg (about twice OpenCV's ``imdecode``
    rate on 1080p, the same pixels: tested): BGR, or its luminance for ``grey`` or a one-channel
    file; with ``scale`` 2, 4 or 8, at ``ceil(size / scale)`` by libjpeg's DCT scaling (the
    inverse DCT of each block's low frequencies: a decode that costs less the smaller it is).
    None where simplejpeg declines (CMYK, a file libjpeg only warns about, not a JPEG): OpenCV
    then decodes it as before, warnings and all."""
    try:
        h, w, space, _sub = simplejpeg.decode_jpeg_header(data)
        if space not in ("Gray", "YCbCr"):
            return None
        out = simplejpeg.decode_jpeg(
            data,
            colorspace="GRAY" if grey or space == "Gray" else "BGR",
            strict=True,
            min_height=-(-h // scale),
            min_width=-(-w // scale),
            min_factor=scale,
        )
    except ValueError:
        return None
    return out[:, :, 0] if out.shape[2] == 1 else out


class VideoSource:
    """Frames of a video file, decoded sequentially by OpenCV's ``VideoCapture``."""

    def __init__(self, path: Path):
        self.path = path
        cap = cv2.VideoCapture(str(path))
        if not cap.isOpened():
            said = library_says()
            raise InputError(f"cannot open video {path}{said or ' (OpenCV VideoCapture failed)'}")
        self._count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
        self.fps = float(cap.get(cv2.CAP_PROP_FPS) or 0.0)
        cap.release()
        if self._count <= 0:
            raise InputError(f"video {path} reports no frames")

    def __len__(self) -> int:
        return self._count

    @property
    def description(self) -> str:
        return str(self.path)

    def read(self, index0: int) -> RawFrame:
        for i, frame in enumerate(self.iterate(index0)):
            if i == 0:
                return frame
        raise InputError(f"video {self.path}: frame {index0 + 1} cannot be decoded")

    def iterate(self, start0: int = 0) -> Iterator[RawFrame]:
        cap = cv2.VideoCapture(str(self.path))
        try:
            if start0:
                cap.set(cv2.CAP_PROP_POS_FRAMES, start0)
            for i in range(start0, self._count):
                ok, image = cap.read()
                if not ok or image is None:
                    raise InputError(
                        f"video {self.path}: frame {i + 1} cannot be decoded{library_says()}"
                    )
                yield RawFrame(image, None)
        finally:
            cap.release()


FrameSource = ImageListSource | VideoSource


def is_grey(image: np.ndarray) -> bool:
    """True for a single-channel frame or a 3-channel frame whose channels agree (+-2 levels)."""
    if image.ndim == 2:
        return True
    if image.ndim == 3 and image.shape[2] == 3:
        sample = image[:: max(image.shape[0] // 64, 1), :: max(image.shape[1] // 64, 1)].astype(
            np.int32
        )
        return bool(
            np.abs(sample[..., 0] - sample[..., 1]).max() <= 2
            and np.abs(sample[..., 1] - sample[..., 2]).max() <= 2
        )
    return False
