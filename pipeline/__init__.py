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

from pipeline._version import __version__
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
