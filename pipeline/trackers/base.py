"""The tracker interface every engine implements.

An engine is started on the first frame pair with the initial targets and then stepped
once per frame pair; both return a :class:`~pipeline.types.FrameResult` with one
:class:`~pipeline.types.TargetResult` per target (box, status, diagnostics)::

    engine = make_tracker("dual", cfg)          # pipeline.trackers
    first = engine.start(frames_1, init_targets)
    for frames in rest:
        result = engine.step(frames)

An engine that looks at the whole sequence before its first frame (the detector's background
of a still camera) has an ``attach(seq)`` method too, which the runner calls before ``start``
(:func:`attach_sequence`).

Our own trackers are pure cores over frozen per-target state (:class:`Core`: ``init(frames,
targets) -> (state, FrameResult)`` and ``step(state, frames) -> (state, FrameResult)``), built
from their configuration section; :class:`CoreEngine` holds the state between calls so the
runner sees the same interface as the OpenCV peers (whose state lives inside OpenCV objects).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Sequence
from typing import Generic, Protocol, TypeVar

from pipeline.io.sequence import FramePair
from pipeline.stages.detection import DetectionConfig
from pipeline.types import FrameResult, InitTarget

S = TypeVar("S")


class Engine(Protocol):
    """What the runner drives: ``start`` on frame 1, then ``step`` on every later frame."""

    name: str

    def start(self, frames: FramePair, targets: Sequence[InitTarget]) -> FrameResult: ...

    def step(self, frames: FramePair) -> FrameResult: ...


class Core(Protocol[S]):
    """A tracker written as pure functions over frozen state: ``init`` on the first frame pair,
    ``step`` on every later one, each returning the new state and the frame's result.

    A core that runs a detector has a ``detection`` attribute (the
    :class:`~pipeline.stages.detection.DetectionConfig` its detector runs with, or None) and a
    ``detector_channel(channels)`` method; its ``init`` then takes a ``background`` keyword and
    its state has a ``background`` field (see :class:`CoreEngine`).
    """

    def init(self, frames: FramePair, targets: Sequence[InitTarget]) -> tuple[S, FrameResult]: ...

    def step(self, state: S, frames: FramePair) -> tuple[S, FrameResult]: ...


class CoreEngine(Generic[S]):
    """The :class:`Engine` over a pure :class:`Core`: it holds the core's state between calls.

    A core with a detector (``core.detection`` not None) is given the background of the whole
    sequence once :meth:`attach` has been called (``detection.background_init = "sequence"``):
    every frame's background (:class:`pipeline.io.background.SequenceBackground`) is put in the
    state before the frame is stepped; with ``core.lazy_background``, as a function of no
    arguments returning it, so that a tracker that seldom runs its detector (the dual tracker's
    whole-frame search) reads the sequence's samples only if it does. Not attached, the state's
    background is whatever the core leaves.

    Parameters
    ----------
    name : str
        The tracker's name (``dualtrack trackers``).
    core : Core
        The tracker.
    warm_ups : sequence of callables
        Called once here, before the first timed frame (numba kernels compiled or loaded).

    Attributes
    ----------
    state : object or None
        The core's state after the last call (public so that tests and tools can inspect or
        replay it).
    """

    def __init__(self, name: str, core: Core[S], warm_ups: Sequence[Callable[[], None]] = ()):
        self.name = name
        self.core = core
        self.state: S | None = None
        self._source = None
        for warm_up in warm_ups:
            warm_up()

    @property
    def detection(self) -> DetectionConfig | None:
        """The settings of the core's detector (None without one)."""
        return getattr(self.core, "detection", None)

    def attach(self, seq) -> None:
        """Give the engine the sequence it will run on: its detector's background comes from
        the whole sequence where the settings ask for it."""
        if self.detection is None:
            return
        from pipeline.io.background import sequence_background

        channel = self.core.detector_channel(tuple(seq.channels))
        self._source = sequence_background(seq, channel, self.detection)

    def camera(self) -> dict[str, object] | None:
        """What the detector's sequence background said of the camera so far
        (:meth:`pipeline.io.background.SequenceBackground.camera`); None without one."""
        return self._source.camera() if self._source is not None else None

    def _background(self, index: int):
        if self._source is None:
            return None
        if getattr(self.core, "lazy_background", False):
            return functools.partial(self._source.at, index)
        return self._source.at(index)

    def start(self, frames: FramePair, targets: Sequence[InitTarget]) -> FrameResult:
        if self.detection is not None:
            background = self._background(frames.index)
            self.state, result = self.core.init(frames, targets, background=background)
        else:
            self.state, result = self.core.init(frames, targets)
        return result

    def step(self, frames: FramePair) -> FrameResult:
        if self.state is None:
            raise RuntimeError(f"{self.name}: step() called before start()")
        if self._source is not None:
            self.state = dataclasses.replace(self.state, background=self._background(frames.index))
        self.state, result = self.core.step(self.state, frames)
        return result


def preferred_channel(channels: tuple[str, ...], preferred: str) -> str:
    """``preferred`` if the sequence has it, else the other channel."""
    if preferred in channels:
        return preferred
    return "visible" if preferred == "infrared" else "infrared"


def attach_sequence(engine: Engine, seq: object) -> None:
    """Give ``engine`` the sequence it will run on, if it has use for it (an ``attach`` method)."""
    attach = getattr(engine, "attach", None)
    if attach is not None:
        attach(seq)


def pick_channel(frames: FramePair, preferred: str = "visible") -> str:
    """The channel a one-channel engine works on: ``preferred`` if present, else the other."""
    if getattr(frames, preferred) is not None:
        return preferred
    return "infrared" if preferred == "visible" else "visible"
