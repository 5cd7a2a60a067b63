"""Tracker engines and their registry (``--tracker NAME``)."""

from __future__ import annotations

from collections.abc import Callable

from pipeline.errors import InputError
from pipeline.trackers import detect as _detect
from pipeline.trackers import dual as _dual
from pipeline.trackers import kalman_camshift as _kc
from pipeline.trackers import meanshift as _meanshift
from pipeline.trackers.base import Engine, FunctionalEngine
from pipeline.trackers.peers import CamShiftEngine, OpenCVEngine, opencv_tracker_available



def _dual_engine(cfg: object) -> Engine:
    from pipeline.stages.contour import warm_up

    warm_up()  # the numba kernels are compiled or loaded here, not inside the timed first frame
    return FunctionalEngine("dual", _dual.init, _dual.step, cfg)


_FACTORIES: dict[str, Callable[[object], Engine]] = {
    "dual": _dual_engine,
    "meanshift": lambda cfg: FunctionalEngine("meanshift", _meanshift.init, _meanshift.step, cfg),
    "kalman-camshift": lambda cfg: FunctionalEngine("kalman-camshift", _kc.init, _kc.step, cfg),
    "detect": lambda cfg: FunctionalEngine("detect", _detect.init, _detect.step, cfg),
    "camshift": lambda cfg: CamShiftEngine(cfg.camshift, cfg.opencv.channel),  # type: ignore[attr-defined]
    "mil": lambda cfg: OpenCVEngine("mil", cfg.opencv),  # type: ignore[attr-defined]
    "csrt": lambda cfg: OpenCVEngine("csrt", cfg.opencv),  # type: ignore[attr-defined]
    "kcf": lambda cfg: OpenCVEngine("kcf", cfg.opencv),  # type: ignore[attr-defined]
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


def register(name: str, factory: Callable[[object], Engine]) -> None:
    _FACTORIES[name] = factory


def make_tracker(name: str, cfg: object) -> Engine:
    """Build the engine ``name`` with the resolved ``PipelineConfig``."""
    factory = _FACTORIES.get(name)
    if factory is None:
        raise InputError(f"unknown tracker {name!r}; available: {', '.join(_FACTORIES)}")
    if name in ("dual", "meanshift", "kalman-camshift"):
        from pipeline.stages.histogram import warm_up

        warm_up()  # the compiled histogram loops are loaded here, not inside the timed first frame
    return factory(cfg)


__all__ = ["DEFAULT_TRACKER", "NEEDS_NO_INIT", "PEERS", "Engine", "available_trackers", "detect_init", "make_tracker",
           "tracker_names"]
