"""dualtrack: tracking in registered infrared + visible video.

Python API (design.md)::

    import pipeline
    seq = pipeline.open_sequence("path/to/sequence")
    results = pipeline.track(seq, tracker="dual", init=[(10, 20, 30, 40)])
    metrics = pipeline.evaluate("path/to/sequence", "runs/seq/tracks.csv")
    pipeline.synthesize("crossing2", "out/crossing2")
"""

from __future__ import annotations

from typing import Any

__version__ = "0.1.0"

_LAZY = {
    "open_sequence": ("pipeline.io.sequence", "open_sequence"),
    "track": ("pipeline.run", "track"),
    "run_track": ("pipeline.run", "run_track"),
    "evaluate": ("pipeline.eval", "evaluate_files"),
    "synthesize": ("pipeline.synthetic", "synthesize"),
    "BBox": ("pipeline.types", "BBox"),
    "PipelineConfig": ("pipeline.config", "PipelineConfig"),
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        mod, attr = _LAZY[name]
        return getattr(importlib.import_module(mod), attr)
    raise AttributeError(f"module 'pipeline' has no attribute {name!r}")


__all__ = ["BBox", "PipelineConfig", "__version__", "evaluate", "open_sequence", "run_track", "synthesize", "track"]
