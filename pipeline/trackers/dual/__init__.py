"""``dual``: visible mean shift, IR level-set contour and a correlation filter over both channels.

The paper (Zhao, Bo, Yin 2012, §2.1-2.3) per frame and target: mean shift on the
kernel-weighted HSV histogram in the visible frame (step 2), the DRLSE contour in the IR frame
around it for the position and the size (step 3), the scale update of eq. 7 and the selective
model update of eq. 8-9 (step 4); and for targets in mutual occlusion eq. 10-11 with one level
set over the merged blob.

The tracker (:class:`Dual`) is composed of parts, each holding only its own section of the
``dual`` configuration (:class:`~pipeline.tracker_config.DualConfig`):

================  =====================  ===========================================
part              module                 does
================  =====================  ===========================================
``motion``        ``motion.py``          the Kalman prior of every search; coasting
``colour``        ``colour.py``          mean shift (step 2); the colour model (eq. 8-9)
``contour``       ``contour.py``         the IR level set (step 3) and its checks
``appearance``    ``appearance.py``      a correlation filter over both channels
``extent``        ``size.py``            the box's sides from the target's colours
``redetector``    ``redetect.py``        where a missing target is looked for
``decider``       ``decide.py``          the rule table: which measurement is taken
``size``          ``size.py``            eq. 7 over the cues' sizes
``lifecycle``     ``lifecycle.py``       lost targets, status events, confidences
``groups``        ``group.py``           eq. 10-11: merge, split, re-association
================  =====================  ===========================================

``appearance``, ``extent``, ``redetector`` and ``groups`` are beyond the paper and optional;
:meth:`Dual.paper` leaves the first three out and puts ``groups`` in (``data/dual-paper.toml``).
"""

from pipeline.tracker_config import DualConfig
from pipeline.trackers.dual.decide import Case, Decider, Decision, Evidence, Rule
from pipeline.trackers.dual.size import scale_update
from pipeline.trackers.dual.state import DualState, DualTarget, GroupMemory
from pipeline.trackers.dual.tracker import Dual, mode_of

__all__ = [
    "Case",
    "Decider",
    "Decision",
    "Dual",
    "DualConfig",
    "DualState",
    "DualTarget",
    "Evidence",
    "GroupMemory",
    "Rule",
    "mode_of",
    "scale_update",
]
