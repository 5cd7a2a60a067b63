"""Tracker engines and their registry (``--tracker NAME``).

Each name maps to a builder that makes the tracker from its own section of the resolved
:class:`~pipeline.config.PipelineConfig` (:data:`pipeline.config.TRACKER_SECTIONS`) and wraps
it in an :class:`~pipeline.trackers.base.Engine`:

==================  ==================================================================
name                built as
==================  ==================================================================
``dual``            ``Dual.from_config(cfg.dual)`` (:mod:`pipeline.trackers.dual`)
``meanshift``       ``MeanShift(cfg.meanshift)``
``kalman-camshift`` ``KalmanCamShift(cfg.kalman_camshift)``
``detect``          ``DetectAndAssociate(cfg.detect)``
``camshift``        ``CamShiftEngine(cfg.camshift, cfg.opencv.channel)``
``mil``, ``csrt``,  ``OpenCVEngine(name, cfg.opencv)`` (CSRT and KCF where the installed
``kcf``             OpenCV has its contrib modules)
==================  ==================================================================
"""

from __future__ import annotations

from collections.abc import Callable

from pipeline.config import PipelineConfig
from pipeline.errors import InputError
from pipeline.stages import detection, histogram
from pipeline.stages import meanshift as meanshift_stage
from pipeline.trackers.base import CoreEngine, Engine
from pipeline.trackers.detect import DetectAndAssociate, detect_init
from pipeline.trackers.dual import Dual
from pipeline.trackers.kalman_camshift import KalmanCamShift
from pipeline.trackers.meanshift import MeanShift
from pipeline.trackers.peers import CamShiftEngine, OpenCVEngine, opencv_tracker_available


def dual_engine(cfg: PipelineConfig) -> Engine:
    """``dual``: the composition of ``cfg.dual``, its kernels compiled before the first frame;
    its whole-frame search gets the sequence's background."""
    core = Dual.from_config(cfg.dual)
    return CoreEngine("dual", core, warm_ups=(core.warm_up,))


def meanshift_engine(cfg: PipelineConfig) -> Engine:
    """``meanshift``: colour-histogram mean shift with a scale search (``cfg.meanshift``)."""
    return CoreEngine("meanshift", MeanShift(cfg.meanshift), warm_ups=(meanshift_stage.warm_up,))


def kalman_camshift_engine(cfg: PipelineConfig) -> Engine:
    """``kalman-camshift``: CamShift from a Kalman prediction (``cfg.kalman_camshift``)."""
    core = KalmanCamShift(cfg.kalman_camshift)
    return CoreEngine("kalman-camshift", core, warm_ups=(histogram.warm_up,))


def detect_engine(cfg: PipelineConfig) -> Engine:
    """``detect``: detection and global association, no initial boxes (``cfg.detect``)."""
    return CoreEngine("detect", DetectAndAssociate(cfg.detect), warm_ups=(detection.warm_up,))


def camshift_engine(cfg: PipelineConfig) -> Engine:
    """``camshift``: OpenCV's CamShift (``cfg.camshift``) on ``cfg.opencv.channel``."""
    return CamShiftEngine(cfg.camshift, cfg.opencv.channel)


def _opencv(name: str) -> Callable[[PipelineConfig], Engine]:
    def build(cfg: PipelineConfig) -> Engine:
        return OpenCVEngine(name, cfg.opencv)

    build.__doc__ = f"``{name}``: OpenCV's {name.upper()} tracker (``cfg.opencv``)."
    return build


TRACKERS: dict[str, Callable[[PipelineConfig], Engine]] = {
    "dual": dual_engine,
    "meanshift": meanshift_engine,
    "kalman-camshift": kalman_camshift_engine,
    "detect": detect_engine,
    "camshift": camshift_engine,
    "mil": _opencv("mil"),
    "csrt": _opencv("csrt"),
    "kcf": _opencv("kcf"),
}
"""Every tracker by name, with the builder that makes it from the resolved configuration."""

PEERS = ("camshift", "mil", "csrt", "kcf")
NEEDS_NO_INIT = ("detect",)
DEFAULT_TRACKER = "dual"


def tracker_names() -> list[str]:
    """Every tracker's name, the default first."""
    return list(TRACKERS)


def available_trackers() -> list[str]:
    """Trackers that can run with the installed OpenCV."""
    return [n for n in TRACKERS if n not in ("csrt", "kcf") or opencv_tracker_available(n)]


def make_tracker(name: str, cfg: PipelineConfig) -> Engine:
    """Build the engine ``name`` from the resolved configuration.

    Examples
    --------
    >>> from pipeline.config import load_config
    >>> engine = make_tracker("dual", load_config(None, ["dual.groups=default"]))
    >>> engine.name, engine.core.groups is not None
    ('dual', True)
    """
    build = TRACKERS.get(name)
    if build is None:
        raise InputError(f"unknown tracker {name!r}; available: {', '.join(TRACKERS)}")
    return build(cfg)


__all__ = [
    "DEFAULT_TRACKER",
    "NEEDS_NO_INIT",
    "PEERS",
    "TRACKERS",
    "Engine",
    "available_trackers",
    "detect_init",
    "make_tracker",
    "tracker_names",
]
