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
        Frames buffered before a columnar write, in [1, 1000]; default 16. The run's
        checkpoints (the recording, the CSV rows and ``summary.json`` made durable) fall on
        multiples of it. Increasing it lowers the logging cost per frame; a process killed
        outright loses the frames since the last checkpoint (an exception or Ctrl-C loses
        none).
    checkpoint_min_seconds : float
        Wall time, in [0, 60] s, that must pass after a checkpoint before the next is taken;
        default 0.5. A checkpoint is Python work on the writer's thread (a columnar write per
        entity, a wait for the file, ``summary.json`` rewritten) that holds the interpreter
        while the tracker waits for it, so a fast tracker slows with every checkpoint. With
        the floor a fast run checkpoints about twice a second, and a kill loses at most about
        this long's frames (rounded up to ``batch_frames``); a run slower than
        ``batch_frames`` frames in this time checkpoints every ``batch_frames`` frames as
        before. 0: every multiple of ``batch_frames``.
    jpeg_quality : int
        JPEG quality, in [1, 100], for frames that have no source bytes to pass through
        (video input, 16-bit or resized IR); default 90.
    """

    section = "rerun"

    batch_frames: int = param(16, ge=1, le=1000)
    checkpoint_min_seconds: float = param(0.5, ge=0, le=60)
    jpeg_quality: int = param(90, ge=1, le=100)
