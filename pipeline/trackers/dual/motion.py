"""The dual tracker's motion part: the Kalman prior of every search, and how a target coasts."""

from __future__ import annotations

import math
from dataclasses import dataclass

from pipeline.stages import kalman
from pipeline.stages.motion import coast_start, hold_rates, stop
from pipeline.tracker_config import MotionConfig
from pipeline.trackers.dual.decide import Case, Decision, Rule
from pipeline.trackers.dual.state import DualTarget, History
from pipeline.types import BBox, TargetStatus

_FOUND_AWAY = (Rule.REDETECTED, Rule.APPEARANCE_AND_COLOUR)
"""The rules that take a missing target back away from where it was believed to be."""


@dataclass(frozen=True)
class Motion:
    """Predicts each target, says where its searches start, and corrects or coasts it.

    Parameters
    ----------
    cfg : MotionConfig
        ``dual.motion``: where searches start, and the coasting line fit.
    kalman : KalmanConfig
        ``dual.kalman``: the motion model.
    """

    cfg: MotionConfig
    kalman: kalman.KalmanConfig

    def start(self, box: BBox) -> kalman.GaussianState:
        """The state of a target given at ``box``, at rest."""
        return kalman.init_state(box, self.kalman)

    def predict(self, t: DualTarget) -> kalman.GaussianState:
        """The prior of this frame: a missing target coasts at constant velocity and size."""
        F, Q = kalman.motion_model(self.kalman)
        missing = t.missing > 0 or t.held
        return kalman.predict_compiled(hold_rates(t.kf, self.kalman) if missing else t.kf, F, Q)

    def search_start(self, t: DualTarget, prior: kalman.GaussianState) -> tuple[float, float]:
        """Where this frame's searches start: the prediction, or (the paper's) the last
        position."""
        if self.cfg.search_from == "prediction":
            return (float(prior.x[0]), float(prior.x[1]))
        return t.box.center

    def correct(
        self, prior: kalman.GaussianState, box: BBox, noise: float = 1.0
    ) -> kalman.GaussianState:
        """``prior`` corrected by a measured ``box`` whose noise is ``noise`` times the model's."""
        Hm, Rm = kalman.measurement_model(self.kalman)
        return kalman.correct_compiled(
            prior, kalman.box_measurement(box), Hm, Rm * noise, self.kalman
        ).state

    @staticmethod
    def stop(kf: kalman.GaussianState) -> kalman.GaussianState:
        """The state of a target given up as lost: every rate zeroed."""
        return stop(kf)

    def update(
        self,
        t: DualTarget,
        prior: kalman.GaussianState,
        decision: Decision,
        out: BBox,
        frame: int,
    ) -> tuple[kalman.GaussianState, History, BBox]:
        """The state after this frame: corrected by the measurement (its noise scaled per
        rule), restarted at rest on a target found again after it was lost, by the widened
        search or far from its prediction (``APPEARANCE_AND_COLOUR``), or coasting (restarted
        at an occlusion's onset from a line through the recent clean measurements, stopped
        once lost). Returns the state, the clean-measurement history and the output box (moved
        to the restarted coast)."""
        if (
            decision.measured
            and decision.case == Case.REACQUIRED
            and (t.status == TargetStatus.LOST or decision.rule in _FOUND_AWAY)
        ):
            # found again after it was given up, by the widened search or far from its
            # prediction: the jump from where it was believed to be is not its motion; the
            # filter restarts at the measurement, at rest
            return self.start(out), ((float(frame), out.cx, out.cy, out.w, out.h),), out
        if decision.measured:
            kf = self.correct(prior, out, max(decision.noise, 1e-6))
            history = t.history
            if decision.case in (Case.CONTOUR, Case.APPEARANCE) and not decision.held:
                clean = (float(frame), out.cx, out.cy, out.w, out.h)
                history = (*history, clean)[-self.cfg.history_frames :]
            return kf, history, out
        return self._coast(t, prior, decision, out, frame)

    def _coast(
        self,
        t: DualTarget,
        prior: kalman.GaussianState,
        decision: Decision,
        out: BBox,
        frame: int,
    ) -> tuple[kalman.GaussianState, History, BBox]:
        kf = prior
        if t.missing == 0:  # an occlusion starts: coast from the recent clean measurements
            cfg = self.cfg
            restart = coast_start(
                t.history,
                prior,
                frame,
                cfg.rewind_frames + cfg.onset_frames,
                cfg.onset_frames,
                cfg.rewind_tolerance or math.inf,
            )
            if restart is not None:
                kf = restart
                ref = t.reference_size
                out = BBox.from_center(float(kf.x[0]), float(kf.x[1]), ref[0], ref[1])
        if decision.status == TargetStatus.LOST:  # a lost target stays where it was last believed
            kf = stop(kf)
        return kf, t.history, out
