"""Sink settings (kept apart from the sinks so that reading them does not import rerun)."""

from __future__ import annotations

from dataclasses import dataclass

from pipeline.params import Section, param


@dataclass(frozen=True)
class RerunConfig(Section):
    """Recording settings.

    Parameters
    ----------
    batch_frames : int
        Frames buffered before a columnar write, in [1, 1000]; default 16. Increasing
        it lowers the logging cost per frame; at most this many frames are lost if the
        process is killed outright (an exception or Ctrl-C loses none).
    jpeg_quality : int
        JPEG quality, in [1, 100], for frames that have no source bytes to pass through
        (video input, 16-bit or resized IR); default 90.
    """

    section = "rerun"

    batch_frames: int = param(16, ge=1, le=1000)
    jpeg_quality: int = param(90, ge=1, le=100)
