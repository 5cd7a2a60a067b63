"""Sequence folders: layout detection, lazy frame pairs, ground truth.

The layouts of docs/formats.md are recognised by their folder and file names:

=============  =================  ==================  ====================================  ====
layout         visible            infrared            ground truth                          base
=============  =================  ==================  ====================================  ====
rgbt234        ``visible/``       ``infrared/``       ``visible.txt``, ``infrared.txt``     0
gtot           ``v/``             ``i/``              ``groundTruth_v.txt``/``_i`` x1y1x2y2 0
vot-rgbt       ``color/``         ``ir/``             ``groundtruth.txt`` (box or polygon)  0
vtuav          ``rgb/``           ``ir/``             ``rgb.txt``/``ir.txt`` xywh every 10  0
video-pair     ``visible.<ext>``  ``infrared.<ext>``  any of the above files if present     0
otb            ``img/`` (colour)  ``img/`` (grey)     ``groundtruth_rect.txt``              1
mot            ``img1/``          ``img1/``           ``gt/gt.txt``                         1
vot            frames in folder   frames in folder    ``groundtruth.txt``                   0
=============  =================  ==================  ====================================  ====

"base" is the coordinate the file gives the first pixel's corner; it is subtracted on
the way in (override with ``gt_base``). VTUAV annotates every 10th frame (frames 1, 11,
21, ... here): the frames between have no truth and are not scored.

A two-channel layout with only one of its halves (``visible/`` + ``visible.txt`` alone, say) is a
one-channel sequence of the channel its folder names; where the folder name fits two layouts
(``ir/``), the layout whose truth file is there is chosen. A MOTChallenge ``gt.txt`` (or
``gt/gt.txt``) beside the frames takes precedence over the single-target files (its base is 1).

Channels of a one-channel folder are decided from the first frame (grey = infrared,
colour = visible) unless ``channel`` says otherwise. 16-bit infrared frames are read as
16-bit; the trackers get them normalized to 8 bits by a per-sequence percentile stretch
(0.5th to 99.5th percentile over up to 16 frames spread over the sequence, mapped to
0..255), and the raw array stays in ``FramePair.infrared_raw``.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from pipeline.errors import InputError
from pipeline.io.frames import (
    IMAGE_EXTENSIONS,
    VIDEO_EXTENSIONS,
    EncodedFrame,
    FrameSource,
    ImageListSource,
    RawFrame,
    VideoSource,
    is_grey,
    list_images,
)
from pipeline.io.groundtruth import (
    MotTruth,
    expand_sparse,
    fit_length,
    parse_box_file,
    parse_mot_truth,
)

CHANNELS = ("visible", "infrared")


@dataclass(frozen=True)
class FramePair:
    """One registered frame pair as the trackers see it.

    Parameters
    ----------
    index : int
        The frame number, from 1.
    visible : (H, W, 3) uint8 array or None
        The visible frame, BGR; None in an infrared-only sequence.
    infrared : (H, W) uint8 array or None
        The infrared frame, normalized to 8 bits; None in a visible-only sequence.
    infrared_raw : (H, W) array, optional
        The IR frame as stored (uint16 for 16-bit sensors).
    visible_encoded, infrared_encoded : EncodedFrame, optional
        The source bytes when the frame came from a JPEG/PNG file that still matches the
        array, or the array at ``scale`` (the recording passes them through).
    scale : int
        The arrays are ``1 / scale`` of the source frames (``Sequence.decode_at``); 1, 2, 4 or 8.

    Examples
    --------
    >>> import numpy as np
    >>> fp = FramePair(1, np.zeros((48, 64, 3), np.uint8), np.zeros((48, 64), np.uint8))
    >>> fp.shape, fp.channels
    ((48, 64), ('visible', 'infrared'))
    """

    index: int
    visible: np.ndarray | None
    infrared: np.ndarray | None
    infrared_raw: np.ndarray | None = None
    visible_encoded: EncodedFrame | None = None
    infrared_encoded: EncodedFrame | None = None
    scale: int = 1

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W) of the frames."""
        img = self.visible if self.visible is not None else self.infrared
        assert img is not None  # a FramePair always has at least one channel
        return img.shape[0], img.shape[1]

    @property
    def channels(self) -> tuple[str, ...]:
        return tuple(c for c in CHANNELS if getattr(self, c) is not None)


@dataclass(frozen=True)
class Truth:
    """Ground truth per channel: ``boxes[channel][id]`` is ``(N, 4)``, NaN rows = no truth.

    For a MOTChallenge ``gt.txt`` both channels share the same table (registered frames)
    and ``visibility[id]`` holds the visibility column; ``distractors[id]`` ``(N, 4)`` are its
    rows of a distractor class (objects that are not targets, see ``parse_mot_truth``).
    ``sparse_every`` says which frames were annotated: frames 1, 1 + every, ... (VTUAV: 10); a
    NaN row on an annotated frame means the target is absent there, on another frame only that
    nobody annotated it.
    """

    boxes: dict[str, dict[int, np.ndarray]] = field(default_factory=dict)
    visibility: dict[int, np.ndarray] = field(default_factory=dict)
    files: dict[str, str] = field(default_factory=dict)
    multi: bool = False
    distractors: dict[int, np.ndarray] = field(default_factory=dict)
    sparse_every: int = 1

    def annotated(self, n_frames: int) -> np.ndarray:
        """``(n_frames,)`` bool: the frames that were annotated (all of them for dense truth).

        Examples
        --------
        >>> Truth(sparse_every=10).annotated(25).nonzero()[0].tolist()  # frames 1, 11, 21
        [0, 10, 20]
        """
        mask = np.zeros(n_frames, bool)
        mask[:: self.sparse_every] = True
        return mask

    def truncated(self, n: int) -> Truth:
        """The truth of the first ``n`` frames."""
        return Truth(
            {c: {i: b[:n] for i, b in d.items()} for c, d in self.boxes.items()},
            {i: v[:n] for i, v in self.visibility.items()},
            self.files,
            self.multi,
            {i: b[:n] for i, b in self.distractors.items()},
            self.sparse_every,
        )

    @property
    def has_truth(self) -> bool:
        return bool(self.boxes)

    def primary_channel(self) -> str | None:
        """Channel scored by default: visible when both have truth, else the one there is."""
        if "visible" in self.boxes:
            return "visible"
        if "infrared" in self.boxes:
            return "infrared"
        return None

    def primary(self) -> dict[int, np.ndarray]:
        ch = self.primary_channel()
        return self.boxes[ch] if ch else {}


@dataclass(frozen=True)
class IrNormalization:
    """How raw IR frames become the 8-bit frames the trackers see."""

    kind: str = "none"  # "none" (8-bit as is) or "percentile"
    low: float = 0.0
    high: float = 255.0

    def apply(self, raw: np.ndarray) -> np.ndarray:
        if raw.ndim == 3:
            raw = cv2.cvtColor(raw, cv2.COLOR_BGR2GRAY) if raw.dtype == np.uint8 else raw[..., 0]
        if self.kind == "none" and raw.dtype == np.uint8:
            return raw
        scale = 255.0 / max(self.high - self.low, 1e-9)
        out = (raw.astype(np.float32) - np.float32(self.low)) * np.float32(scale)
        return np.clip(out + 0.5, 0, 255).astype(np.uint8)


@dataclass(frozen=True)
class _Spec:
    name: str
    visible: str | None
    infrared: str | None
    gt: dict[str, tuple[str, str]]  # channel -> (file, form); channel "both" = shared
    base: float = 0.0
    sparse_every: int = 1


_PAIR_LAYOUTS = (
    _Spec(
        "rgbt234",
        "visible",
        "infrared",
        {"visible": ("visible.txt", "xywh"), "infrared": ("infrared.txt", "xywh")},
    ),
    _Spec(
        "gtot",
        "v",
        "i",
        {"visible": ("groundTruth_v.txt", "xyxy"), "infrared": ("groundTruth_i.txt", "xyxy")},
    ),
    _Spec("vot-rgbt", "color", "ir", {"both": ("groundtruth.txt", "xywh")}),
    _Spec(
        "vtuav",
        "rgb",
        "ir",
        {"visible": ("rgb.txt", "xywh"), "infrared": ("ir.txt", "xywh")},
        sparse_every=10,
    ),
)
_ONE_CHANNEL_LAYOUTS = (
    _Spec("otb", "img", "img", {"both": ("groundtruth_rect.txt", "xywh")}, base=1.0),
    _Spec("mot", "img1", "img1", {}, base=1.0),
    _Spec("vot", ".", ".", {"both": ("groundtruth.txt", "xywh")}),
)
LAYOUT_NAMES = (
    "rgbt234/lasher (visible/ + infrared/)",
    "gtot (v/ + i/)",
    "vot-rgbt (color/ + ir/)",
    "vtuav (rgb/ + ir/)",
    "video pair (visible.<video> + infrared.<video>)",
    "otb (img/)",
    "mot (img1/)",
    "vot (frames in the folder)",
)


class Sequence:
    """A sequence folder opened for tracking. Frames stream lazily via :meth:`frames`.

    Use :func:`open_sequence` to build one.
    """

    def __init__(
        self,
        path: Path,
        layout: str,
        sources: dict[str, FrameSource],
        truth: Truth,
        ir_norm: IrNormalization,
        size: tuple[int, int],
        ir_resize: tuple[int, int] | None,
        init_file: Path | None,
        meta: dict[str, object] | None = None,
        warnings: tuple[str, ...] = (),
    ):
        self.path = path
        self.meta = meta or {}
        """The sequence's ``scene.json`` (synthetic scenes: seed, visibility, attributes), read
        once; {} without one."""
        self.warnings = warnings
        """Things about the input worth saying that do not stop a run (truth rows that do not
        match the frames)."""
        self.name = path.name
        self.layout = layout
        self.sources = sources
        self.truth = truth
        self.ir_norm = ir_norm
        self.width, self.height = size
        self.ir_resize = ir_resize  # original IR (W, H) when IR is resized to the visible size
        self.init_file = init_file
        self.n_frames = len(next(iter(sources.values())))
        self.scale = 1
        """Frames are read at ``1 / scale`` of their size (:meth:`decode_at`)."""

    def decode_at(self, scale: int) -> None:
        """Read every frame from now on at ``1 / scale`` of its size (1, 2, 4 or 8): JPEG files
        decoded there by libjpeg's DCT scaling, other frames resized (area average) to
        ``ceil(size / scale)``. ``width`` and ``height`` stay the source's; the frames'
        ``scale`` says by how much their arrays are smaller."""
        if scale not in (1, 2, 4, 8):
            raise ValueError(f"decode scale must be 1, 2, 4 or 8; got {scale}")
        self.scale = scale
        for src in self.sources.values():
            if isinstance(src, ImageListSource):
                src.scale = scale

    @property
    def scaled_size(self) -> tuple[int, int]:
        """(W, H) of the frames as read: the source's size over :attr:`scale`, rounded up."""
        return -(-self.width // self.scale), -(-self.height // self.scale)

    def __len__(self) -> int:
        return self.n_frames

    def __repr__(self) -> str:
        return (
            f"Sequence({self.name!r}, layout={self.layout!r}, channels={self.channels}, "
            f"frames={self.n_frames}, size={self.width}x{self.height})"
        )

    @property
    def channels(self) -> tuple[str, ...]:
        return tuple(c for c in CHANNELS if c in self.sources)

    def frames(
        self, start: int = 1, stop: int | None = None, workers: int = 1
    ) -> Iterator[FramePair]:
        """Frame pairs ``start..stop`` (1-based, inclusive), in order.

        ``workers`` > 1 decodes that many frame pairs at once on threads, up to ``4 * workers``
        ahead (image files only: a video is decoded in order, on the caller's thread); the
        decoders release the GIL, so the pairs come up to ``workers`` times as fast.
        """
        stop = self.n_frames if stop is None else min(stop, self.n_frames)
        if workers > 1 and all(isinstance(s, ImageListSource) for s in self.sources.values()):
            yield from self._frames_parallel(start, stop, workers)
            return
        iters = {c: s.iterate(start - 1) for c, s in self.sources.items()}
        for index in range(start, stop + 1):
            raw = {c: next(it) for c, it in iters.items()}
            yield self._pair(index, raw)

    def _frames_parallel(self, start: int, stop: int, workers: int) -> Iterator[FramePair]:
        from collections import deque
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(workers, thread_name_prefix="dualtrack-decode") as pool:
            ahead: deque = deque()
            nxt = start
            try:
                while ahead or nxt <= stop:
                    while nxt <= stop and len(ahead) < 4 * workers:
                        ahead.append(pool.submit(self.frame, nxt))
                        nxt += 1
                    yield ahead.popleft().result()
            finally:
                for f in ahead:
                    f.cancel()

    def frame(self, index: int, channels: Iterable[str] | None = None) -> FramePair:
        """One frame pair by its 1-based number; with ``channels``, only those are read and
        decoded (the others are None)."""
        if not 1 <= index <= self.n_frames:
            raise IndexError(f"frame {index} outside 1..{self.n_frames}")
        want = self.sources if channels is None else set(channels)
        return self._pair(
            index, {c: s.read(index - 1) for c, s in self.sources.items() if c in want}
        )

    def _pair(self, index: int, raw: dict[str, RawFrame]) -> FramePair:
        vis = raw.get("visible")
        ir = raw.get("infrared")
        size = self.scaled_size
        visible = None
        if vis is not None:
            img = self._at_scale(index, "visible", vis.image, (self.width, self.height))
            if img.dtype != np.uint8:
                img = cv2.convertScaleAbs(img, alpha=255.0 / max(float(img.max()), 1.0))
            visible = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR) if img.ndim == 2 else img
        infrared = ir_raw = ir_enc = None
        if ir is not None:
            own = self.ir_resize or (self.width, self.height)
            ir_raw = self._at_scale(index, "infrared", ir.image, own)
            infrared = self.ir_norm.apply(ir_raw)
            if self.ir_resize is not None:  # the source bytes no longer match: the sink re-encodes
                infrared = cv2.resize(infrared, size, interpolation=cv2.INTER_LINEAR)
            else:
                ir_enc = ir.encoded  # None for 16-bit frames (frames.py)
        return FramePair(
            index=index,
            visible=visible,
            infrared=infrared,
            infrared_raw=ir_raw,
            visible_encoded=vis.encoded if vis is not None else None,
            infrared_encoded=ir_enc,
            scale=self.scale,
        )

    def _at_scale(
        self, index: int, channel: str, img: np.ndarray, own: tuple[int, int]
    ) -> np.ndarray:
        """``img`` (a channel's frame, ``own`` (W, H) at full size) at :attr:`scale`: checked
        against its size, as decoded (a JPEG already at scale) or area-resized there."""
        if self.scale == 1:
            self._check_size(index, channel, img, own)
            return img
        small = (-(-own[0] // self.scale), -(-own[1] // self.scale))
        if (img.shape[1], img.shape[0]) == small:
            return img
        self._check_size(index, channel, img, own)
        return cv2.resize(img, small, interpolation=cv2.INTER_AREA)

    def _check_size(
        self, index: int, channel: str, img: np.ndarray, expect: tuple[int, int] | None = None
    ) -> None:
        w, h = expect if expect is not None else (self.width, self.height)
        if img.shape[1] != w or img.shape[0] != h:
            raise InputError(
                f"frame {index}: {channel} frame is {img.shape[1]}x{img.shape[0]}, "
                f"expected {w}x{h} like the first frame"
            )


def _find_dir(root: Path, name: str) -> Path | None:
    if name == ".":
        return root
    for cand in (root / name, root / name.upper(), root / name.capitalize()):
        if cand.is_dir():
            return cand
    return None


def _find_video(root: Path, stem: str) -> Path | None:
    for p in sorted(root.iterdir()):
        if p.is_file() and p.stem.lower() == stem and p.suffix.lower() in VIDEO_EXTENSIONS:
            return p
    return None


def _images_or_error(folder: Path, channel: str, grey: bool = False) -> ImageListSource:
    paths = list_images(folder)
    if not paths:
        raise InputError(
            f"empty sequence: no {channel} frames ({', '.join(IMAGE_EXTENSIONS)}) in {folder}"
        )
    return ImageListSource(paths, grey=grey)


def _find_mot_gt(root: Path, frames_dir: Path | None) -> Path | None:
    for cand in (root / "gt" / "gt.txt", root / "gt.txt"):
        if cand.is_file():
            return cand
    if frames_dir is not None and frames_dir != root:
        for cand in (frames_dir / "gt.txt",):
            if cand.is_file():
                return cand
    return None


def _one_half(root: Path) -> tuple[_Spec, str, Path] | None:
    """A two-channel layout of which only one channel's folder holds frames: (layout, channel,
    folder)."""
    found: list[tuple[_Spec, str, Path]] = []
    for s in _PAIR_LAYOUTS:
        for ch, name in (("visible", s.visible), ("infrared", s.infrared)):
            d = _find_dir(root, name or "")
            if d is not None and list_images(d):
                found.append((s, ch, d))
    if not found:
        return None
    for s, ch, d in found:  # the layout whose truth file for that channel is there
        fname = s.gt.get(ch, s.gt.get("both", ("", "")))[0]
        if fname and (root / fname).is_file():
            return s, ch, d
    return found[0]


def sequence_layout(path: str | Path) -> str | None:
    """The layout name of a sequence folder, without reading any frame; None when ``path``
    holds no frames in any layout :func:`open_sequence` knows (used to find sequences under
    an archive root)."""
    root = Path(path)
    if not root.is_dir():
        return None
    for s in _PAIR_LAYOUTS:
        vd, idir = _find_dir(root, s.visible or ""), _find_dir(root, s.infrared or "")
        if vd is not None and idir is not None and list_images(vd) and list_images(idir):
            return s.name
    if _find_video(root, "visible") is not None and _find_video(root, "infrared") is not None:
        return "video-pair"
    half = _one_half(root)
    if half is not None:
        return half[0].name
    for s in _ONE_CHANNEL_LAYOUTS:
        d = _find_dir(root, s.visible or "")
        if d is not None and list_images(d):
            return s.name
    return None


def open_sequence(
    path: str | Path,
    *,
    channel: str | None = None,
    align: str = "none",
    gt_base: float | None = None,
) -> Sequence:
    """Open a sequence folder of any layout docs/formats.md names.

    Parameters
    ----------
    path : str or Path
        The sequence folder.
    channel : {"visible", "infrared"}, optional
        In a one-channel folder, what its frames are (default: decided from the first
        frame, grey = infrared). In a two-channel folder, keep only that channel.
    align : {"none", "resize"}
        ``resize`` scales infrared frames (and infrared truth) to the visible size when
        the sizes differ; otherwise different sizes are an error.
    gt_base : float, optional
        Override of the layout's ground-truth coordinate base (0 or 1).

    Returns
    -------
    Sequence
        The folder's frames (read lazily: :meth:`Sequence.frames`, :meth:`Sequence.frame`),
        its channels, layout, frame count and truth (0-based boxes per channel and id).

    Raises
    ------
    InputError
        Missing folder, unrecognised layout, no frames, unreadable first frame,
        channels with different frame counts or sizes, malformed ground truth.

    Examples
    --------
    >>> import tempfile
    >>> from pipeline import open_sequence, synthesize
    >>> seq = open_sequence(synthesize("crossing2", tempfile.mkdtemp() + "/c", progress=False))
    >>> seq.layout, seq.channels, sorted(seq.truth.primary())
    ('rgbt234', ('visible', 'infrared'), [1, 2])
    >>> open_sequence(seq.path, channel="infrared").channels
    ('infrared',)
    """
    root = Path(path)
    if not root.exists():
        raise InputError(f"sequence folder not found: {root}")
    if not root.is_dir():
        raise InputError(f"not a folder: {root} (point dualtrack at a sequence folder)")
    if channel not in (None, "visible", "infrared"):
        raise InputError(f"--channel must be 'visible' or 'infrared'; got {channel!r}")
    if align not in ("none", "resize"):
        raise InputError(f"--align must be 'none' or 'resize'; got {align!r}")

    spec: _Spec | None = None
    sources: dict[str, FrameSource] = {}
    frames_dir: Path | None = None
    for s in _PAIR_LAYOUTS:
        vd, idir = _find_dir(root, s.visible or ""), _find_dir(root, s.infrared or "")
        if vd is not None and idir is not None:
            spec = s
            sources = {
                "visible": _images_or_error(vd, "visible"),
                "infrared": _images_or_error(idir, "infrared", grey=True),
            }
            frames_dir = vd
            break
    if spec is None:
        vv, iv = _find_video(root, "visible"), _find_video(root, "infrared")
        if vv is not None and iv is not None:
            spec = _Spec("video-pair", None, None, {})
            sources = {"visible": VideoSource(vv), "infrared": VideoSource(iv)}
    if spec is None:
        half = _one_half(root)
        if half is not None:
            spec, found_ch, frames_dir = half
            if channel is not None and channel != found_ch:
                raise InputError(
                    f"--channel {channel}: {root} holds only {found_ch} frames ({frames_dir})"
                )
            sources = {
                found_ch: ImageListSource(list_images(frames_dir), grey=found_ch == "infrared")
            }
    if spec is None:
        for s in _ONE_CHANNEL_LAYOUTS:
            d = _find_dir(root, s.visible or "")
            if d is not None and list_images(d):
                spec, frames_dir = s, d
                src = ImageListSource(list_images(d))
                if channel is None:
                    channel_found = "infrared" if is_grey(src.read(0).image) else "visible"
                else:
                    channel_found = channel
                src.grey = channel_found == "infrared"
                sources = {channel_found: src}
                break
    if spec is None:
        if any(p.is_dir() for p in root.iterdir()) or not any(root.iterdir()):
            found = (
                ", ".join(sorted(p.name + ("/" if p.is_dir() else "") for p in root.iterdir())[:8])
                or "nothing"
            )
            raise InputError(
                f"unrecognised sequence layout in {root} (found {found}); looked for: "
                + "; ".join(LAYOUT_NAMES)
            )
        raise InputError(f"empty sequence: no frames in {root}")

    if channel is not None and len(sources) == 2:
        sources = {channel: sources[channel]}

    counts = {c: len(s) for c, s in sources.items()}
    if len(set(counts.values())) > 1:
        v, i = (sources["visible"], sources["infrared"])
        raise InputError(
            f"channels have different frame counts: {counts['visible']} visible frames in "
            f"{v.description} vs {counts['infrared']} infrared frames in {i.description}"
        )
    n = next(iter(counts.values()))
    if n == 0:
        raise InputError(f"empty sequence: no frames in {root}")

    first = {c: s.read(0) for c, s in sources.items()}
    sizes = {c: (f.image.shape[1], f.image.shape[0]) for c, f in first.items()}
    ir_resize = None
    if len(sizes) == 2 and sizes["visible"] != sizes["infrared"]:
        if align != "resize":
            (vw, vh), (iw, ih) = sizes["visible"], sizes["infrared"]
            raise InputError(
                f"channels have different frame sizes: visible {vw}x{vh} "
                f"({sources['visible'].description}) "
                f"vs infrared {iw}x{ih} ({sources['infrared'].description}); pass --align resize "
                "to scale "
                "infrared to the visible size"
            )
        ir_resize = sizes["infrared"]
    size = sizes.get("visible", sizes.get("infrared"))
    assert size is not None

    ir_norm = IrNormalization()
    if "infrared" in sources and first["infrared"].image.dtype != np.uint8:
        ir_norm = _percentile_norm(sources["infrared"])

    if gt_base is not None and gt_base not in (0, 1):
        raise InputError(
            "--gt-base must be 0 or 1 (the coordinate of the first pixel's corner); got "
            f"{gt_base:g}"
        )
    warnings: list[str] = []
    truth = _load_truth(root, spec, frames_dir, n, gt_base, sources, warnings)
    if ir_resize is not None and "infrared" in truth.boxes and not truth.multi:
        sx, sy = size[0] / ir_resize[0], size[1] / ir_resize[1]
        truth.boxes["infrared"] = {
            k: v * np.array([sx, sy, sx, sy]) for k, v in truth.boxes["infrared"].items()
        }
    init_file = root / "init.txt" if (root / "init.txt").is_file() else None
    if init_file is not None and not truth.has_truth:
        lines = _box_lines(init_file)
        if lines > 1:  # RGBT234's init.txt is one target's truth, a box per frame
            warnings.append(
                f"{init_file} has {lines} boxes: read as one target's box per frame (the RGBT234 "
                "convention), started from the first; to start several targets, give the file "
                "with --init-file (one x,y,w,h per target)"
            )
    return Sequence(
        root,
        spec.name,
        sources,
        truth,
        ir_norm,
        size,
        ir_resize,
        init_file,
        read_scene_json(root, warnings),
        tuple(warnings),
    )


def _box_lines(path: Path) -> int:
    """Non-empty lines of a box file (0 when it cannot be read: the reader says why later)."""
    try:
        return sum(1 for line in path.read_text(errors="replace").splitlines() if line.strip())
    except OSError:
        return 0


def read_scene_json(folder: Path, warnings: list[str] | None = None) -> dict[str, object]:
    """A sequence folder's ``scene.json`` as a dict ({} when there is none or it cannot be
    read)."""
    import json

    f = Path(folder) / "scene.json"
    if not f.is_file():
        return {}
    try:
        data = json.loads(f.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        if warnings is not None:
            warnings.append(
                f"{f}: not readable as JSON ({type(exc).__name__}); its attributes are ignored"
            )
        return {}
    return data if isinstance(data, dict) else {}


def _percentile_norm(src: FrameSource, samples: int = 16) -> IrNormalization:
    n = len(src)
    idx = np.unique(np.linspace(0, n - 1, min(samples, n)).round().astype(int))
    vals = []
    for i in idx:
        img = src.read(int(i)).image
        vals.append(img[::4, ::4].ravel())
    allv = np.concatenate(vals).astype(np.float64)
    lo, hi = np.percentile(allv, [0.5, 99.5])
    if hi <= lo:
        hi = lo + 1.0
    return IrNormalization("percentile", float(lo), float(hi))


def _truth_files(root: Path, spec: _Spec) -> list[tuple[str, str, str, float, int]]:
    """``(channel, file, form, coordinate base, annotated every)`` of each single-target truth
    file of the layout that is there; a video pair takes any file the folder layouts know, with
    that layout's base and sparseness (VTUAV's ``rgb.txt`` / ``ir.txt``: every 10th frame)."""
    specs = [spec]
    if spec.name == "video-pair":
        specs = [*_PAIR_LAYOUTS, _ONE_CHANNEL_LAYOUTS[0]]
    out, seen = [], set()
    for s in specs:
        for ch, (fname, form) in s.gt.items():
            if ch not in seen and (root / fname).is_file():
                seen.add(ch)
                out.append((ch, fname, form, s.base, s.sparse_every))
    return out


def _load_truth(
    root: Path,
    spec: _Spec,
    frames_dir: Path | None,
    n: int,
    gt_base: float | None,
    sources: dict[str, FrameSource],
    warnings: list[str],
) -> Truth:
    mot = _find_mot_gt(root, frames_dir)
    if mot is not None:
        mt: MotTruth = parse_mot_truth(mot, n, base=1.0 if gt_base is None else gt_base)
        if mt.last_frame > n:
            warnings.append(
                f"{mot} has rows up to frame {mt.last_frame} for a sequence of {n} frames "
                "(ignored)"
            )
        if mt.duplicates:
            f, t = mt.duplicates[0]
            warnings.append(
                f"{mot}: {len(mt.duplicates)} duplicate (frame, id) rows, the first frame {f} "
                f"id {t}; the last row of each counts"
            )
        boxes = {c: mt.boxes for c in sources}
        return Truth(
            boxes,
            mt.visibility,
            {c: str(mot) for c in sources},
            multi=True,
            distractors=mt.distractors,
        )
    boxes: dict[str, dict[int, np.ndarray]] = {}
    files: dict[str, str] = {}
    every = 1
    for ch, fname, form, base, sparse in _truth_files(root, spec):
        f = root / fname
        arr = parse_box_file(f, form, base if gt_base is None else gt_base)
        want = -(-n // sparse)
        if arr.shape[0] != want:
            one_every = f" (one every {sparse} frames)" if sparse > 1 else ""
            fate = (
                "the extra rows are ignored"
                if arr.shape[0] > want
                else "the frames past them have no truth"
            )
            warnings.append(
                f"{f} has {arr.shape[0]} rows for {n} frames{one_every}, {want} expected; {fate}"
            )
        arr = expand_sparse(arr, n, sparse) if sparse > 1 else fit_length(arr, n)
        every = max(every, sparse)
        targets = ("visible", "infrared") if ch == "both" else (ch,)
        for c in targets:
            if c in sources:
                boxes[c] = {1: arr}
                files[c] = str(f)
    return Truth(boxes, {}, files, multi=False, sparse_every=every)
