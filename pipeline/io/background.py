"""A still camera's background for the detector, read from the sequence itself.

:class:`SequenceBackground` reads ``detection.background_samples`` frames spread over a block
of ``detection.background_window_frames`` frames (and half a block either side) and gives
their registered low quantile (:func:`pipeline.stages.detection.quantile_background`) to every
frame of the block. The detector's runners (``dualtrack detect``, ``--tracker detect``,
``--detect``, the dual tracker's whole-frame search) make one per run when
``detection.background_init = "sequence"``.
"""

from __future__ import annotations

import cv2
import numpy as np

from pipeline.errors import InputError
from pipeline.io.sequence import Sequence
from pipeline.stages.detection import Background, DetectionConfig, quantile_background, to_grey


class SequenceBackground:
    """The background of every frame of ``seq`` on ``channel``, one block at a time.

    Parameters
    ----------
    seq : Sequence
        The sequence, read in any order (:meth:`Sequence.frame`).
    channel : str
        ``infrared`` or ``visible``: the frames the detector runs on.
    cfg : DetectionConfig
        ``background_samples``, ``background_window_frames``, ``max_shift_px``; with
        ``fuse_visible`` on the IR channel, the visible frames' median too.

    Notes
    -----
    A sampled frame that cannot be read is left out of the estimate; when none of a block's
    can, :meth:`at` returns None and the detector bootstraps from the frame it is given.
    The block in use is cached: a sequence of N frames costs
    ``ceil(N / background_window_frames) * background_samples`` extra frame reads.
    A block whose samples the camera saw from elsewhere (:attr:`Background.holds` False: a
    moving camera) is remembered; :meth:`camera` reports them.
    """

    def __init__(self, seq: Sequence, channel: str, cfg: DetectionConfig):
        self.seq = seq
        self.channel = channel
        self.cfg = cfg
        self._block: int | None = None
        self._bg: Background | None = None
        self._moved: dict[int, tuple[int, int]] = {}  # block -> (moved samples, samples)
        self._last = 0

    def block_frames(self, block: int) -> range:
        """The 1-based frames whose background block ``block``'s is."""
        w = self.cfg.background_window_frames
        return range(block * w + 1, min((block + 1) * w, self.seq.n_frames) + 1)

    def camera(self) -> dict[str, object]:
        """What the background's samples said of the camera, over the frames asked for so far:
        ``moving`` (some frame's block does not hold), ``moving_frames`` (how many frames are in
        such blocks), ``frames`` (asked for), and per such block its first and last frame and how
        many of its samples were seen from elsewhere."""
        blocks = [
            {"frames": [r.start, min(r.stop - 1, self._last)], "moved_samples": m, "samples": n}
            for b, (m, n) in sorted(self._moved.items())
            if (r := self.block_frames(b)).start <= self._last
        ]
        frames = sum(b["frames"][1] - b["frames"][0] + 1 for b in blocks)  # type: ignore[index]
        return {
            "moving": bool(blocks),
            "moving_frames": frames,
            "frames": self._last,
            "blocks": blocks,
        }

    def sample_indices(self, block: int) -> list[int]:
        """The 1-based frames block ``block``'s background is estimated from."""
        n, w = self.seq.n_frames, self.cfg.background_window_frames
        lo = max(1, block * w + 1 - w // 2)
        hi = min(n, (block + 1) * w + w // 2)
        k = min(self.cfg.background_samples, hi - lo + 1)
        return sorted({round(v) for v in np.linspace(lo, hi, k)})

    def at(self, index: int) -> Background | None:
        """The background of frame ``index`` (1-based)."""
        block = (index - 1) // self.cfg.background_window_frames
        self._last = max(self._last, index)
        if block != self._block:
            self._block, self._bg = block, self._estimate(block)
            if self._bg is not None and not self._bg.holds:
                self._moved[block] = (self._bg.moved_samples, self._bg.frames)
        return self._bg

    def _estimate(self, block: int) -> Background | None:
        fuse = self.cfg.uses_visible and self.channel == "infrared"
        greys, labs = [], []
        channels = {self.channel, "visible"} if fuse else {self.channel}
        for i in self.sample_indices(block):
            try:
                fp = self.seq.frame(i, channels)  # only what the estimate reads is decoded
            except (InputError, OSError, IndexError):
                continue
            img = getattr(fp, self.channel)
            if img is None:
                continue
            greys.append(to_grey(img))
            if fuse and fp.visible is not None and fp.visible.shape[:2] == greys[-1].shape:
                labs.append(cv2.cvtColor(fp.visible, cv2.COLOR_BGR2LAB).astype(np.float32))
        if not greys or any(g.shape != greys[0].shape for g in greys):
            return None
        return quantile_background(greys, self.cfg, labs if len(labs) == len(greys) else None)


def camera_warning(camera: dict[str, object], consequence: str) -> str | None:
    """The one line a run says about a moving camera (:meth:`SequenceBackground.camera`), or
    None for a still one; ``consequence`` says what the run did about it."""
    if not camera.get("moving"):
        return None
    return (
        f"the camera moves on {camera['moving_frames']} of {camera['frames']} frames: a still "
        "camera's background does not hold there (its samples were seen from elsewhere), so the "
        f"detector's regions there are the scene's own texture as much as targets; {consequence}"
    )


def sequence_background(
    seq: Sequence, channel: str, cfg: DetectionConfig
) -> SequenceBackground | None:
    """A :class:`SequenceBackground` when the configuration asks for one (``method = foreground``,
    ``background_init = sequence``), else None (the detector keeps its running background)."""
    if cfg.method != "foreground" or cfg.background_init != "sequence":
        return None
    return SequenceBackground(seq, channel, cfg)
