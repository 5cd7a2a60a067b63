"""``dual``: visible mean shift, IR level-set contour and a correlation filter over both channels.

The paper (Zhao, Bo, Yin 2012, §2.1-2.3) per frame and target: mean shift on the kernel-weighted
HSV histogram in the visible frame (step 2), the DRLSE contour in the IR frame around it for the
position and the size (step 3), the scale update of eq. 7 and the selective model update of
eq. 8-9 (step 4); and for targets in mutual occlusion eq. 10-11 with one level set over the
merged blob (``group.py``).

Beyond the paper, each behind a flag of :class:`DualConfig` (``data/dual-paper.toml`` turns them
all off): a correlation filter over both channels (``pipeline.stages.appearance``) that decides
where the contour and the colour disagree, measures the size, and re-detects a hidden target;
contour checks; channel weighting; a Kalman motion prior.

The parts: ``cues.py`` measures (motion prior, mean shift, filter), ``decide.py`` decides which
measurement is taken and which status follows (one function for the dual, IR-only and
visible-only modes), ``update.py`` updates size, models and motion, ``single.py`` and
``group.py`` wire them for a free target and a merged group, ``tracker.py`` runs the frame.
"""

from pipeline.tracker_config import DualConfig
from pipeline.trackers.dual.decide import Case, Decision, Evidence, decide
from pipeline.trackers.dual.state import DualState, DualTarget, GroupMemory
from pipeline.trackers.dual.tracker import init, mode_of, step
from pipeline.trackers.dual.update import scale_update

__all__ = [
    "Case",
    "Decision",
    "DualConfig",
    "DualState",
    "DualTarget",
    "Evidence",
    "GroupMemory",
    "decide",
    "init",
    "mode_of",
    "scale_update",
    "step",
]
