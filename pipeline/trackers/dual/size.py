"""The dual tracker's size part: eq. 7 over the filter's scale, the contour and the colour
extent, and the size of a target that walks in through the frame's border."""

from __future__ import annotations

from dataclasses import dataclass

from pipeline.stages import extent as ext
from pipeline.stages.contour import ContourResult
from pipeline.tracker_config import SizeConfig
from pipeline.trackers.dual.appearance import FilterCue
from pipeline.trackers.dual.colour import ColourStep
from pipeline.trackers.dual.decide import Decision
from pipeline.types import BBox

Size = tuple[float, float]


def scale_update(h: Size, h_contour: Size, rate: float) -> Size:
    """Eq. 7: ``h_new = (1 - a) h + a h_contour`` for width and height.

    Examples
    --------
    >>> scale_update((20.0, 40.0), (30.0, 40.0), 0.2)
    (22.0, 40.0)
    """
    return ((1 - rate) * h[0] + rate * h_contour[0], (1 - rate) * h[1] + rate * h_contour[1])


@dataclass(frozen=True)
class ExtentCue:
    """The target's extent in its colours (beyond the paper): the box's width and height each on
    its own.

    Parameters
    ----------
    cfg : ExtentConfig
        ``dual.extent``: the window, the likelihood ratio and how far the size may follow it.
    """

    cfg: ext.ExtentConfig

    def measure(
        self, cs: ColourStep, center: tuple[float, float], neighbours: tuple[BBox, ...]
    ) -> BBox | None:
        """The colour extent (frame px) around ``center`` at the target's current size; None
        where another target (``neighbours``, their boxes this frame) lies within the extent's
        window, or where the colour does not show it."""
        if cs.bins is None:
            return None
        here = BBox.from_center(center[0], center[1], cs.t.size[0], cs.t.size[1])
        win = ext.search_window(here, self.cfg)
        if any(win.iou(b) > 0 for b in neighbours):
            return None
        x0, y0 = cs.roi0
        around = BBox(here.x - x0, here.y - y0, here.w, here.h)
        e = ext.colour_extent(cs.bins, cs.t.q, around, self.cfg)
        return None if e is None else BBox(e.x + x0, e.y + y0, e.w, e.h)


@dataclass(frozen=True)
class SizeModel:
    """How the box's size follows the cues each frame.

    Parameters
    ----------
    cfg : SizeConfig
        ``dual.size``: eq. 7's rate, how far the contour may differ from the filter's size, and
        the contrast a contour's size needs.
    """

    cfg: SizeConfig

    def update(
        self,
        size: Size,
        app_size: Size,
        decision: Decision,
        contour_size: Size | None,
        cue: FilterCue | None,
        filter_confident: bool,
        extent: BBox | None = None,
        extent_ratio: float = 1.0,
    ) -> tuple[Size, Size]:
        """The size after this frame and the filter's own size: ``(size, app_size)``.

        The filter's size follows its scale estimate alone, when it is confident. The size
        follows the same change, then eq. 7 towards ``contour_size`` (the contour's box when
        it may enter the size: clean, clearly contrasted; else None); with a filter, only a
        contour within ``scale_agree_ratio`` of the filter's size counts, and the size stays
        within that ratio of it. A contour that covers part of the target, or leaks into a
        neighbour, so cannot drag the size: it is measured against a size it never entered.
        With a filter, the colour ``extent`` (when measured) moves width and height each at
        eq. 7's rate towards it where it is larger than the filter's size (a smaller one means
        part of the target has the background's colours), and the size may exceed the
        filter's by ``extent_ratio`` per axis (1: by ``scale_agree_ratio`` only).
        """
        if not decision.measured:
            return size, app_size
        base = size
        if cue is not None and filter_confident:
            f = cue.scale_factor
            base, app_size = (size[0] * f, size[1] * f), (app_size[0] * f, app_size[1] * f)
        r = self.cfg.scale_agree_ratio
        if contour_size is not None and (cue is None or _within(contour_size, app_size, r)):
            base = scale_update(base, contour_size, self.cfg.scale_rate)
        if cue is None:
            return base, app_size
        if extent is not None:
            # the colour shows where a target is wider or taller than the filter's size; a
            # smaller extent only means that part of it has the background's colours
            grown = (max(extent.w, app_size[0]), max(extent.h, app_size[1]))
            base = scale_update(base, grown, self.cfg.scale_rate)
        up = max(r, extent_ratio)
        return (
            min(max(base[0], app_size[0] / r), app_size[0] * up),
            min(max(base[1], app_size[1] / r), app_size[1] * up),
        ), app_size

    def walked_in(
        self,
        size: Size,
        c: ContourResult | None,
        colour_contradicts: bool,
        entering: tuple[bool, bool],
    ) -> Size | None:
        """The size of a target first given cut by the frame's border, once it has walked in:
        its first clean contour (no longer at the border, its colour not contradicting it) is
        larger than the given box by more than ``scale_agree_ratio`` along a cut axis. None
        otherwise (also when the target was not cut after all)."""
        if c is None or c.box is None or not c.ok or colour_contradicts:
            return None
        found = (c.box.w, c.box.h)
        grown = _grown(found, size, entering, self.cfg.scale_agree_ratio)
        if not any(grown):
            return None
        return (found[0] if grown[0] else size[0], found[1] if grown[1] else size[1])


def _grown(found: Size, size: Size, entering: tuple[bool, bool], ratio: float) -> list[bool]:
    """Per axis: cut by the border at the start, and now larger than ``size`` by ``ratio``."""
    return [entering[k] and found[k] > ratio * size[k] for k in (0, 1)]


def _within(a: Size, b: Size, ratio: float) -> bool:
    """Each side of ``a`` within a factor ``ratio`` of ``b``'s."""
    return 1 / ratio <= a[0] / b[0] <= ratio and 1 / ratio <= a[1] / b[1] <= ratio
