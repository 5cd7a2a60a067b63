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
    """

    def __init__(self, seq: Sequence, channel: str, cfg: DetectionConfig):
        self.seq = seq
        self.channel = channel
        self.cfg = cfg
        self._block: int | None = None
        self._bg: Background | None = None

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
        if block != self._block:
            self._block, self._bg = block, self._estimate(block)
        return self._bg

    def _estimate(self, block: int) -> Background | None:
        fuse = self.cfg.uses_visible and self.channel == "infrared"
        greys, labs = [], []
        for i in self.sample_indices(block):
            try:
                fp = self.seq.frame(i)
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


def sequence_background(
    seq: Sequence, channel: str, cfg: DetectionConfig
) -> SequenceBackground | None:
    """A :class:`SequenceBackground` when the configuration asks for one (``method = foreground``,
    ``background_init = sequence``), else None (the detector keeps its running background)."""
    if cfg.method != "foreground" or cfg.background_init != "sequence":
        return None
    return SequenceBackground(seq, channel, cfg)
