"""Trackers to drive from your own loop: ``start`` on the first frames with the boxes, ``step`` on
every later one.

Every engine of ``dualtrack trackers`` is available as :class:`Tracker` (by name); the
project's own trackers also have a class of their own: :class:`DualTracker`,
:class:`MeanShiftTracker`, :class:`KalmanCamShiftTracker` and :class:`DetectTracker`.
Frames are given as a :class:`~pipeline.io.sequence.FramePair` or as ``(visible, infrared)``
arrays (``(H, W, 3)`` uint8 BGR and ``(H, W)`` uint8; either may be None), boxes as
:class:`~pipeline.types.BBox` or ``(x, y, w, h)`` in 0-based pixel coordinates.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np

from pipeline.config import PipelineConfig
from pipeline.errors import InputError
from pipeline.io.sequence import FramePair
from pipeline.types import BBox, FrameResult, InitTarget

Frames = FramePair | tuple[np.ndarray | None, np.ndarray | None]


def _grey(infrared: np.ndarray | None) -> np.ndarray | None:
    """An infrared frame as one channel: ``cv2.imread``'s default three equal channels (or a
    single-channel third axis) become ``(H, W)``."""
    if infrared is None or infrared.ndim != 3 or infrared.dtype != np.uint8:
        return infrared
    if infrared.shape[2] == 1:
        return infrared[..., 0]
    if infrared.shape[2] == 3:
        import cv2

        return cv2.cvtColor(infrared, cv2.COLOR_BGR2GRAY)
    return infrared


def _frame_pair(frames: Frames, index: int) -> FramePair:
    if isinstance(frames, FramePair):
        return frames
    try:
        visible, infrared = frames
    except (TypeError, ValueError):
        raise InputError(
            "frames must be a FramePair or a (visible, infrared) pair of arrays"
        ) from None
    if visible is None and infrared is None:
        raise InputError("frames: at least one of visible and infrared must be given")
    if visible is not None and (
        visible.ndim != 3 or visible.shape[2] != 3 or visible.dtype != np.uint8
    ):
        raise InputError(
            f"the visible frame must be (H, W, 3) uint8 BGR; got {visible.shape} {visible.dtype}"
        )
    infrared = _grey(infrared)
    if infrared is not None and (infrared.ndim != 2 or infrared.dtype != np.uint8):
        raise InputError(
            "the infrared frame must be (H, W) uint8 (or the (H, W, 3) copy cv2.imread gives); "
            f"got {infrared.shape} {infrared.dtype}"
        )
    if visible is not None and infrared is not None and visible.shape[:2] != infrared.shape:
        raise InputError(
            f"visible {visible.shape[:2]} and infrared {infrared.shape} frames differ in size"
        )
    return FramePair(index, visible, infrared)


class Tracker:
    """The tracker ``name`` (any of ``dualtrack trackers``), stepped frame by frame.

    Parameters
    ----------
    config : PipelineConfig, optional
        Every stage's parameters; default ``PipelineConfig()`` (the defaults of the CLI).
    name : str, optional
        The engine; default the class's own (``dual`` for :class:`Tracker`).

    Examples
    --------
    A warm, red square moving right by 2 px a frame:

    >>> import numpy as np
    >>> from pipeline import BBox, DualTracker
    >>> def frames(x):
    ...     vis = np.full((120, 160, 3), 90, np.uint8)
    ...     ir = np.full((120, 160), 60, np.uint8)
    ...     vis[40:80, x:x + 20] = (40, 40, 200)
    ...     ir[40:80, x:x + 20] = 200
    ...     return vis, ir
    >>> trk = DualTracker()
    >>> first = trk.start(frames(60), [BBox(60, 40, 20, 40)])
    >>> for k in range(1, 6):
    ...     result = trk.step(frames(60 + 2 * k))
    >>> t = result.targets[0]
    >>> round(t.box.x), t.status.value
    (70, 'tracking')
    """

    default_name = "dual"

    def __init__(self, config: PipelineConfig | None = None, name: str | None = None):
        from pipeline.trackers import make_tracker

        self.config = config if config is not None else PipelineConfig()
        self.name = name or self.default_name
        self._engine = make_tracker(self.name, self.config)
        self._index = 0

    def start(
        self, frames: Frames, boxes: Iterable[BBox | tuple[float, float, float, float]] = ()
    ) -> FrameResult:
        """Start on the first frames with the targets' boxes (ids 1..N); returns their result for
        this frame."""
        targets: list[InitTarget] = []
        for i, b in enumerate(boxes, start=1):
            box = b if isinstance(b, BBox) else BBox(*map(float, b))
            if not (box.w > 0 and box.h > 0):
                raise InputError(
                    f"box {i} must have a positive width and height; got {box.as_tuple()}"
                )
            targets.append(InitTarget(i, box))
        self._index = 1
        return self._engine.start(_frame_pair(frames, 1), targets)

    def step(self, frames: Frames) -> FrameResult:
        """Track into the next frames."""
        if self._index == 0:
            raise InputError("call start() before step()")
        self._index += 1
        return self._engine.step(_frame_pair(frames, self._index))

    def track(
        self,
        frames: Sequence[Frames],
        boxes: Iterable[BBox | tuple[float, float, float, float]] = (),
    ) -> list[FrameResult]:
        """``start`` on ``frames[0]`` and ``step`` through the rest: one result per frame."""
        if not frames:
            raise InputError("no frames to track")
        out = [self.start(frames[0], boxes)]
        out += [self.step(f) for f in frames[1:]]
        return out


class DualTracker(Tracker):
    """The dual-channel tracker (``dual``): colour mean shift, IR contour, correlation filter (see
    :class:`Tracker`, whose example drives it).

    Parameters
    ----------
    config : PipelineConfig, optional
        Its section is ``config.dual``, one sub-section per part; default ``PipelineConfig()``.
        :meth:`paper` is the paper's composition.

    Examples
    --------
    >>> from pipeline import DualTracker
    >>> DualTracker().config.dual.groups is None, DualTracker.paper().config.dual.groups is None
    (True, False)
    """

    default_name = "dual"

    @classmethod
    def paper(cls) -> DualTracker:
        """The paper's dual tracker: the composition of
        :meth:`~pipeline.tracker_config.DualConfig.paper` (``data/dual-paper.toml``)."""
        from pipeline.tracker_config import DualConfig

        return cls(PipelineConfig(dual=DualConfig.paper()))


class MeanShiftTracker(Tracker):
    """Kernel-weighted colour histogram mean shift (``meanshift``; see :class:`Tracker`).

    Parameters
    ----------
    config : PipelineConfig, optional
        Its section is ``config.meanshift``; default ``PipelineConfig()``.

    Examples
    --------
    >>> import numpy as np
    >>> def frames(x):  # a warm red square on a grey ground
    ...     vis = np.full((120, 160, 3), 90, np.uint8)
    ...     ir = np.full((120, 160), 60, np.uint8)
    ...     vis[40:80, x:x + 20] = (40, 40, 200)
    ...     ir[40:80, x:x + 20] = 200
    ...     return vis, ir
    >>> trk = MeanShiftTracker()
    >>> _ = trk.start(frames(60), [(60, 40, 20, 40)])
    >>> abs(trk.step(frames(63)).targets[0].box.x - 63) < 1.5
    True
    """

    default_name = "meanshift"


class KalmanCamShiftTracker(Tracker):
    """CamShift from a Kalman prediction with graded occlusion (``kalman-camshift``; see
    :class:`Tracker`).

    Parameters
    ----------
    config : PipelineConfig, optional
        Its section is ``config.kalman_camshift``; default ``PipelineConfig()``.

    Examples
    --------
    >>> import numpy as np
    >>> def frames(x):  # a warm red square on a grey ground
    ...     vis = np.full((120, 160, 3), 90, np.uint8)
    ...     ir = np.full((120, 160), 60, np.uint8)
    ...     vis[40:80, x:x + 20] = (40, 40, 200)
    ...     ir[40:80, x:x + 20] = 200
    ...     return vis, ir
    >>> trk = KalmanCamShiftTracker()
    >>> _ = trk.start(frames(60), [(60, 40, 20, 40)])
    >>> result = trk.step(frames(62))
    >>> result.targets[0].status.value, abs(result.targets[0].box.cx - 72) < 2
    ('tracking', True)
    """

    default_name = "kalman-camshift"


class DetectTracker(Tracker):
    """Targets found by the detector and associated globally (``detect``; see
    :class:`Tracker`): ``start`` takes no boxes.

    Parameters
    ----------
    config : PipelineConfig, optional
        Its section is ``config.detect``; default ``PipelineConfig()``.

    Examples
    --------
    A warm target on a flat infrared ground, found without a box and confirmed after three
    detections:

    >>> import numpy as np
    >>> def frame(x):
    ...     ir = np.full((120, 160), 60, np.uint8)
    ...     ir[40:80, x:x + 14] = 200
    ...     return None, ir
    >>> trk = DetectTracker()
    >>> results = trk.track([frame(40 + 2 * k) for k in range(6)])
    >>> [r.targets[0].status.value for r in results[:4]]
    ['tentative', 'tentative', 'tracking', 'tracking']
    """

    default_name = "detect"


__all__ = [
    "DetectTracker",
    "DualTracker",
    "Frames",
    "KalmanCamShiftTracker",
    "MeanShiftTracker",
    "Tracker",
]
