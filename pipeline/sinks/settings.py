"""Sink settings (kept apart from the sinks so that reading them does not import rerun)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class RerunConfig:
    """Recording settings.

    Parameters
    ----------
    batch_frames : int
        Frames buffered before a columnar write, in [1, 1000]; default 16. Increasing
        it lowers the logging cost per frame; at most this many frames are lost if the
        process is killed outright (an exception or Ctrl-C loses none).
    jpeg_quality : int
        JPEG quality, 1..100, for frames that have no source bytes to pass through
        (video input, 16-bit or resized IR); default 90.
    """

    batch_frames: int = 16
    jpeg_quality: int = 90

    def __post_init__(self) -> None:
        if not 1 <= self.batch_frames <= 1000:
            raise ValueError(f"rerun.batch_frames must be in [1, 1000]; got {self.batch_frames!r}")
        if not 1 <= self.jpeg_quality <= 100:
            raise ValueError(f"rerun.jpeg_quality must be in [1, 100]; got {self.jpeg_quality!r}")
