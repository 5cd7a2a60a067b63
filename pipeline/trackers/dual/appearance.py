"""The dual tracker's appearance cue: a correlation filter over both channels (beyond the
paper)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from pipeline.io.sequence import FramePair
from pipeline.stages import appearance as app
from pipeline.stages.model_update import UpdateDecision
from pipeline.trackers.dual.decide import Decision
from pipeline.types import BBox


def filter_images(frames: FramePair, mode: str) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The (visible, infrared) frames the correlation filter sees in a mode."""
    return (
        frames.visible if mode in ("dual", "visible") else None,
        frames.infrared if mode in ("dual", "ir") else None,
    )


@dataclass(frozen=True)
class FilterCue:
    """The filter's best detection of a target in one frame (frame px, clipped to the frame)."""

    box: BBox
    psr: float
    scale_factor: float
    redetected: bool  # found by the widened or whole-frame search, not at the prediction
    support: tuple[float, float] = (float("nan"), float("nan"))  # (visible, IR) PSR at the peak
    scale_samples: app.ScaleSamples | None = None  # the scale filter's, for its learning
    window_samples: app.WindowSamples | None = None  # the translation filter's, likewise


@dataclass(frozen=True)
class AppearanceCue:
    """Trains, detects with and updates each target's correlation filter.

    Parameters
    ----------
    cfg : AppearanceConfig
        ``dual.appearance``: features, the filter, its learning and its scale search.
    """

    cfg: app.AppearanceConfig

    def train(self, frames: FramePair, mode: str, box: BBox) -> app.AppearanceModel:
        """A new filter of the target in ``box``."""
        vis, ir = filter_images(frames, mode)
        return app.train(vis, ir, box, self.cfg)

    def with_scale(self, frame: int) -> bool:
        """The scale is estimated on this frame (every ``scale_every_frames``)."""
        return frame % self.cfg.scale_every_frames == 0

    def detect(
        self,
        model: app.AppearanceModel,
        frames: FramePair,
        mode: str,
        center: tuple[float, float],
        size: tuple[float, float],
        with_scale: bool = True,
    ) -> app.Detection:
        """The filter's detection around ``center`` at ``size``."""
        vis, ir = filter_images(frames, mode)
        return app.detect(model, vis, ir, center, self.cfg, size=size, with_scale=with_scale)

    def rescale(self, model: app.AppearanceModel, d: app.Detection, frames: FramePair, mode: str):
        """``d`` with the scale filter's size at its centre."""
        vis, ir = filter_images(frames, mode)
        return app.rescale(model, d, vis, ir, self.cfg)

    def anchor_due(self, first: app.AppearanceModel | None, frames: FramePair, mode: str) -> bool:
        """The size is checked against the first filter ``first`` on this frame: every
        ``anchor_every_frames``-th, where the filter reads a visible frame."""
        every = self.cfg.anchor_every_frames
        return (
            first is not None
            and every > 0
            and frames.index % every == 0
            and filter_images(frames, mode)[0] is not None
        )

    def anchored(
        self,
        first: app.AppearanceModel | None,
        d: app.Detection,
        frames: FramePair,
        mode: str,
    ) -> app.Detection:
        """``d`` with its size moved by the target's first filter ``first``
        (:func:`pipeline.stages.appearance.anchor_factor`) on every ``anchor_every_frames``-th
        frame where the filter reads a visible frame; ``d`` itself on the others, on infrared
        alone, without a first filter, or with the check off."""
        if not self.anchor_due(first, frames, mode):
            return d
        vis, ir = filter_images(frames, mode)
        c = app.anchor_factor(first, d, vis, ir, self.cfg)
        if c == 1.0:
            return d
        return replace(d, size=(d.size[0] * c, d.size[1] * c), scale_factor=d.scale_factor * c)

    def cue(self, d: app.Detection, frames: FramePair, redetected: bool) -> FilterCue:
        """The detection ``d`` as the cue the decider reads, its centre kept in the frame."""
        H, W = frames.shape
        cx = min(max(d.center[0], 0.0), float(W))
        cy = min(max(d.center[1], 0.0), float(H))
        box = BBox.from_center(cx, cy, d.size[0], d.size[1])
        return FilterCue(
            box,
            d.psr,
            d.scale_factor,
            redetected,
            d.support,
            d.scale_samples,
            d.window_samples,
        )

    def learn(
        self,
        model: app.AppearanceModel | None,
        frames: FramePair,
        mode: str,
        box: BBox,
        decision: Decision,
        colour: UpdateDecision,
        informative: bool,
        frame: int,
        reuse: app.ScaleSamples | None = None,
        reuse_window: app.WindowSamples | None = None,
        support: tuple[float, float] | None = None,
    ) -> app.AppearanceModel | None:
        """The filter blended with this frame when the decision lets the models learn and the
        colour's selective update did not freeze for a change of appearance (eq. 8-9 gates the
        filter's learning rate); on every ``update_every_frames``-th frame only, at the rate
        compounded over them. ``reuse``, ``reuse_window``: this frame's scale samples and search
        window (``scale_reuse_px``, ``window_reuse_px``); ``support`` its detection's (visible,
        IR) PSR (``scale_channels = "adaptive"``)."""
        acfg = self.cfg
        if (
            model is None
            or not decision.measured
            or not decision.learn
            or frame % acfg.update_every_frames
        ):
            return model
        if informative and not colour.update and colour.reason in ("rho-low", "occluded"):
            return model
        k = acfg.update_every_frames
        ks = acfg.scale_every_frames  # the scale filter learns on the frames it estimates on
        scale_rate = (
            1 - (1 - acfg.scale_learning_rate) ** math.lcm(k, ks) if frame % ks == 0 else 0.0
        )
        vis, ir = filter_images(frames, mode)
        return app.update(
            model,
            vis,
            ir,
            box,
            acfg,
            rate=1 - (1 - acfg.learning_rate) ** k,
            scale_rate=scale_rate,
            reuse=reuse,
            reuse_window=reuse_window,
            support=support,
        )
