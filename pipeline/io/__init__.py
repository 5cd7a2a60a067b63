"""Sequence readers, ground-truth and init parsing, result files."""

from pipeline.io.frames import EncodedFrame
from pipeline.io.init import resolve_init
from pipeline.io.results import TrackTable, read_tracks
from pipeline.io.sequence import FramePair, Sequence, Truth, open_sequence

__all__ = [
    "EncodedFrame",
    "FramePair",
    "Sequence",
    "TrackTable",
    "Truth",
    "open_sequence",
    "read_tracks",
    "resolve_init",
]
