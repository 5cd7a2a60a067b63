"""dualtrack: tracking in registered infrared + visible video.

The Python API:

* :class:`DualTracker` (and :class:`Tracker` for any engine by name) to drive from your own loop:
  ``start(frames, boxes)``, then ``step(frames)``;
* :func:`track` a sequence folder in memory, :func:`run_track` it into a run folder (CSV, .rrd,
  plots);
* :func:`open_sequence` to read a folder of any supported layout, :func:`evaluate` a results file
  against its truth, :func:`synthesize` a scene with exact ground truth;
* :class:`PipelineConfig` (every stage's parameters) and :func:`load_config` (TOML and ``--set``
  items).

Examples
--------
>>> import pipeline
>>> cfg = pipeline.load_config(None, ["dual.size.scale_rate=0.3"])
>>> cfg.dual.size.scale_rate
0.3
>>> pipeline.BBox(10, 20, 30, 40).center
(25.0, 40.0)
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from pipeline._version import __version__

# The API is imported on first use (PEP 562): ``import pipeline`` and the ``dualtrack`` command
# start without numpy, OpenCV or Rerun, so the command handles Ctrl-C from its first instant.
_WHERE = {
    "DetectTracker": "pipeline.api",
    "DualTracker": "pipeline.api",
    "KalmanCamShiftTracker": "pipeline.api",
    "MeanShiftTracker": "pipeline.api",
    "Tracker": "pipeline.api",
    "PipelineConfig": "pipeline.config",
    "load_config": "pipeline.config",
    "evaluate": "pipeline.eval",
    "FramePair": "pipeline.io.sequence",
    "open_sequence": "pipeline.io.sequence",
    "RunOptions": "pipeline.run",
    "run_track": "pipeline.run",
    "track": "pipeline.run",
    "synthesize": "pipeline.synthetic",
    "synthesize_random": "pipeline.synthetic",
    "BBox": "pipeline.types",
    "FrameResult": "pipeline.types",
    "TargetResult": "pipeline.types",
    "TargetStatus": "pipeline.types",
}
_RENAMED = {"evaluate": "evaluate_files"}


def __getattr__(name: str) -> object:
    where = _WHERE.get(name)
    if where is None:
        raise AttributeError(f"module 'pipeline' has no attribute {name!r}")
    value = getattr(importlib.import_module(where), _RENAMED.get(name, name))
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *_WHERE])


if TYPE_CHECKING:
    from pipeline.api import (
        DetectTracker,
        DualTracker,
        KalmanCamShiftTracker,
        MeanShiftTracker,
        Tracker,
    )
    from pipeline.config import PipelineConfig, load_config
    from pipeline.eval import evaluate_files as evaluate
    from pipeline.io.sequence import FramePair, open_sequence
    from pipeline.run import RunOptions, run_track, track
    from pipeline.synthetic import synthesize, synthesize_random
    from pipeline.types import BBox, FrameResult, TargetResult, TargetStatus

__all__ = [
    "BBox",
    "DetectTracker",
    "DualTracker",
    "FramePair",
    "FrameResult",
    "KalmanCamShiftTracker",
    "MeanShiftTracker",
    "PipelineConfig",
    "RunOptions",
    "TargetResult",
    "TargetStatus",
    "Tracker",
    "__version__",
    "evaluate",
    "load_config",
    "open_sequence",
    "run_track",
    "synthesize",
    "synthesize_random",
    "track",
]
