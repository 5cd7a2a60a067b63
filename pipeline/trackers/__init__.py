"""Tracker engines and their registry (``--tracker NAME``)."""

from __future__ import annotations

from collections.abc import Callable

from pipeline.config import PipelineConfig
from pipeline.errors import InputError
from pipeline.stages import appearance, contour, histogram
from pipeline.stages.detection import infrared_only
from pipeline.trackers import detect as _detect
from pipeline.trackers import dual as _dual
from pipeline.trackers import kalman_camshift as _kc
from pipeline.trackers import meanshift as _meanshift
from pipeline.trackers.base import BackgroundEngine, Engine, FunctionalEngine
from pipeline.trackers.peers import CamShiftEngine, OpenCVEngine, opencv_tracker_available


def _engine(
    name: str,
    init: Callable,
    step: Callable,
    *warm_ups: Callable[[], None],
    background: bool = False,
) -> Callable[[PipelineConfig], Engine]:
    """Factory of a functional engine that first compiles or loads its numba kernels (``warm_ups``,
    once per process), so that the tracker's first timed frame does not pay for them; with
    ``background``, one whose detector gets the sequence's background
    (:class:`~pipeline.trackers.base.BackgroundEngine`)."""

    def make(cfg: PipelineConfig) -> Engine:
        for warm_up in warm_ups:
            warm_up()
        if background:
            return BackgroundEngine(
                name,
                init,
                step,
                cfg,
                _dual_detector_channel,
                lazy=True,
                detection=lambda c: infrared_only(c.detection),
            )
        return FunctionalEngine(name, init, step, cfg)

    return make


def _dual_detector_channel(channels: tuple[str, ...], cfg: PipelineConfig) -> str:
    """The dual tracker's whole-frame search detects in the IR frame, in the visible one without
    IR."""
    return "infrared" if "infrared" in channels else "visible"


_FACTORIES: dict[str, Callable[[PipelineConfig], Engine]] = {
    "dual": _engine(
        "dual",
        _dual.init,
        _dual.step,
        histogram.warm_up,
        contour.warm_up,
        appearance.warm_up,
        background=True,
    ),
    "meanshift": _engine("meanshift", _meanshift.init, _meanshift.step, histogram.warm_up),
    "kalman-camshift": _engine("kalman-camshift", _kc.init, _kc.step, histogram.warm_up),
    "detect": _detect.make_engine,
    "camshift": lambda cfg: CamShiftEngine(cfg.camshift, cfg.opencv.channel),
    "mil": lambda cfg: OpenCVEngine("mil", cfg.opencv),
    "csrt": lambda cfg: OpenCVEngine("csrt", cfg.opencv),
    "kcf": lambda cfg: OpenCVEngine("kcf", cfg.opencv),
}
PEERS = ("camshift", "mil", "csrt", "kcf")
NEEDS_NO_INIT = ("detect",)
detect_init = _detect.detect_init
DEFAULT_TRACKER = "dual"


def tracker_names() -> list[str]:
    return list(_FACTORIES)


def available_trackers() -> list[str]:
    """Trackers that can run with the installed OpenCV."""
    return [n for n in _FACTORIES if n not in ("csrt", "kcf") or opencv_tracker_available(n)]


def register(name: str, factory: Callable[[PipelineConfig], Engine]) -> None:
    _FACTORIES[name] = factory


def make_tracker(name: str, cfg: PipelineConfig) -> Engine:
    """Build the engine ``name`` with the resolved ``PipelineConfig``."""
    factory = _FACTORIES.get(name)
    if factory is None:
        raise InputError(f"unknown tracker {name!r}; available: {', '.join(_FACTORIES)}")
    return factory(cfg)


__all__ = [
    "DEFAULT_TRACKER",
    "NEEDS_NO_INIT",
    "PEERS",
    "Engine",
    "available_trackers",
    "detect_init",
    "make_tracker",
    "tracker_names",
]
