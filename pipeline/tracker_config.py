"""The trackers' own configuration trees: one section per tracker, one sub-section per part.

A tracker's section (``dual``, ``meanshift``, ``kalman_camshift``, ``detect``; the peers'
``camshift`` and ``opencv``) holds the sections of the parts it is built from, each a frozen
dataclass with its own parameters; the stage sections (``pipeline.stages.*``) appear under
every tracker that runs the stage. The keys of ``--set`` and of a TOML file follow that tree::

    dualtrack track SEQ --set dual.decider.psr_confident=8 --set dual.levelset.timestep=0.2

    [dual.appearance]
    learning_rate = 0.02

A part that a tracker may run without is an optional section: ``dual.appearance``,
``dual.extent``, ``dual.redetect`` and ``dual.groups`` are ``none`` to leave the part out
(``--set dual.groups=none``; ``--set dual.groups=default`` or any of its keys puts it in).

The tree lives here rather than in the trackers, so that :mod:`pipeline.config` gathers it
without importing a tracker.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from pipeline.params import Section, param
from pipeline.stages.appearance import AppearanceConfig
from pipeline.stages.association import AssociationConfig
from pipeline.stages.contour import ContourConfig
from pipeline.stages.detection import DetectionConfig
from pipeline.stages.extent import ExtentConfig
from pipeline.stages.histogram import HistogramConfig
from pipeline.stages.kalman import KalmanConfig
from pipeline.stages.levelset import LevelSetConfig
from pipeline.stages.meanshift import MeanShiftConfig
from pipeline.stages.model_update import ModelUpdateConfig
from pipeline.stages.occlusion import OcclusionConfig
from pipeline.stages.roi_match import RoiMatchConfig


@dataclass(frozen=True)
class MotionConfig(Section):
    """The dual tracker's motion part: where each search starts, and how a hidden target coasts.

    The Kalman model itself is the ``kalman`` section beside this one.

    Parameters
    ----------
    search_from : str
        Where every search of a frame starts: ``prediction`` (default, beyond the paper: the
        Kalman prediction, which also carries hidden targets) or ``last-position`` (the
        paper: where the target was in the previous frame).
    history_frames : int
        Clean measurements kept for the coasting line fit, in [2, 100]; default 16.
    rewind_frames : int
        When an occlusion starts, the coast restarts from a straight line through the recent
        clean measurements if its newest one is at most this old, in [0, 30]; default 8; 0
        never.
    onset_frames : int
        The newest measurements left out of that fit (an occluder may have been cutting them
        already), in [0, 10]; default 4.
    rewind_tolerance : float
        The rewind is refused when one of those left-out measurements lies farther from the
        line than this share of the target's size on either axis (the target turned or
        stopped: the line is the motion it had before), >= 0; default 0.5. An occluder that
        cuts a target shifts its centre by under half its size; 0 rewinds always.
    """

    section = "motion"

    search_from: str = param("prediction", choices=("prediction", "last-position"))
    history_frames: int = param(16, ge=2, le=100)
    rewind_frames: int = param(8, ge=0, le=30)
    onset_frames: int = param(4, ge=0, le=10)
    rewind_tolerance: float = param(0.5, ge=0)


@dataclass(frozen=True)
class ColourConfig(Section):
    """The dual tracker's colour cue (the paper's step 2): when it runs and where it searches.

    The histogram, the mean shift and the selective model update (eq. 8-9) are the
    ``histogram``, ``meanshift`` and ``model_update`` sections beside this one.

    Parameters
    ----------
    dark_gating : bool
        Beyond the paper: the colour cue is skipped where too few of the kernel's pixels are
        bright enough to carry colour (dusk, darkness); default True (False runs it always,
        as the paper does).
    min_value : int
        Visible pixels darker than this (HSV value) carry no colour, in [0, 255]; default 40.
    min_fraction : float
        With ``dark_gating``, the colour cue runs when at least this share of the kernel's
        pixels is bright enough, in [0, 1]; default 0.3.
    missing_search_scale : float
        While a target is missing, its colour search region is this many times larger, in
        [1, 5]; default 2.
    first_model_excludes_nearer : bool
        Beyond the paper: a target's first colour model leaves out the pixels of the other
        targets given on that frame whose boxes overlap its box and reach lower in the frame
        (:func:`pipeline.stages.occlusion.nearer_overlapping`: nearer, where targets stand on
        one ground), so that a target given partly behind another does not take that one's
        colours for its own; default True. Seen from straight above, the order is arbitrary
        and a target loses the pixels another's box overlaps; False counts every pixel of the
        box (the paper's model).
    first_model_min_uncovered : float
        With ``first_model_excludes_nearer``, the pixels left must hold at least this share
        of the box's kernel weight, in [0, 1]; default 0.05. Below it the whole box counts: a
        target given almost wholly hidden has too few pixels of its own to be told from its
        surroundings, and its model would be the background's at its box's rim. The kernel
        weighs the box's centre most, so a target half hidden at its middle keeps about a
        fifth of the weight.
    """

    section = "colour"

    dark_gating: bool = True
    min_value: int = param(40, ge=0, le=255)
    min_fraction: float = param(0.3, ge=0, le=1)
    missing_search_scale: float = param(2.0, ge=1, le=5)
    first_model_excludes_nearer: bool = True
    first_model_min_uncovered: float = param(0.05, ge=0, le=1)


@dataclass(frozen=True)
class RedetectConfig(Section):
    """The dual tracker's re-detector: the search for a hidden or lost target.

    A missing target is looked for by its correlation filter in a region that widens while it
    is missing and, after ``global_after_frames``, at the regions the detector (the
    ``detection`` sub-section) finds in the whole frame.

    Parameters
    ----------
    radius_px_per_frame : float
        The search region around a hidden target's prediction grows by this per missing
        frame, px, >= 0; default 3.
    last_seen : bool
        The widening search region lies around the hidden target's last clean measurement as
        well as around its prediction (the candidates shared between the two), and widens at
        the target's speed (the larger of its net displacement a frame and its mean step, which
        a target walking to and fro keeps high) where that exceeds ``radius_px_per_frame``, so
        that a target that turned or stopped while hidden is found where it was; default True.
    unknown_speed_px_per_frame : float
        The widening region of a target whose speed is not known yet (fewer than two clean
        measurements and no speed from before: given, and lost on its next frame) grows at
        least this fast, px per frame, >= 0; default 10 (0: at ``radius_px_per_frame``). It is
        about twice the motion model's prior deviation of a new target's velocity (``kalman``'s
        ``initial_velocity_std_px_per_frame``, 5): a small target faster than its filter's
        window on its second frame (a walker 8 px wide at 8 px a frame) is otherwise outrun by
        a region widening at 3 px a frame, and coasts at rest until the whole-frame search.
        Raising it spreads the region's places (and its detector regions) wider on such a
        target's first searches.
    global_after_frames : int
        Missing frames after which the whole frame is searched, >= 1; default 12. It tries
        the detector's regions, except those inside another target's box this frame (a
        look-alike another target holds is that target).
    first_model : bool
        The search also tries, at each place, the target's filter as trained on its first
        frame (for a target walking in, on the frame it is whole by), and takes the better
        peak: a filter that learned something else before the target was lost (a passer-by,
        an occluder's edge, a partly hidden view) does not also stop it from being found
        again; default True. It doubles the search's filter evaluations (a missing target's
        only); a target whose look has changed since its first frame is found by its current
        filter as before.
    every_frames : int
        A missing target is searched for every this many frames, >= 1; default 2.
    candidates : int
        At most this many places are tried by one search, >= 1; default 12 (a larger region
        is covered over successive searches). The cost of a search grows with it.
    regions_in_radius : bool
        Before ``global_after_frames``, the search also tries the detector's regions whose
        centres lie within the widening region (first, then its grid of places), except those
        inside another target's box this frame; default True. A target that turned or sped up
        while hidden is often beyond the grid's next places but stands out against the
        background; inside another target's box a region is more likely that target. It runs
        the detector on every search frame of a missing target (4-5 ms a 320 x 240 frame).
    min_region_area_ratio : float
        The whole-frame search tries the detector's regions of this share of the target's
        box area up to four times it (the closest in size first), in (0, 1]; default 0.05.
        A region much smaller than the target is a part of it (a torso, a wheel, the warm
        lines of a cyclist whose frame and legs are at the ground's temperature), and the
        filter's window around it (``1 + padding`` times the size) covers the whole target.
        Raising it to 0.25 tries only regions of about the target's size: a target the
        detector sees in fragments is then not searched for at all.
    detection : DetectionConfig
        The detector of the whole-frame search (run on the IR frame, the visible one without
        IR; its visible-channel regions are never asked for). Its regions are not grown
        (``grow_k`` 0 here): the search takes their centres, and grown ones moved the
        development range both ways (P@20 -0.002 on one target, +0.004 on many). Its
        sequence background is taken over 13 frames (``background_samples``, 25 for the
        ``detect`` tracker): it costs half (36 -> 16 ms a 400-frame block at 320 x 240) and
        the development range did not move beyond its noise (P@20 +0.0004 on one target,
        IDF1 -0.002 on many).
    """

    section = "redetect"

    radius_px_per_frame: float = param(3.0, ge=0)
    last_seen: bool = True
    unknown_speed_px_per_frame: float = param(10.0, ge=0)
    global_after_frames: int = param(12, ge=1)
    first_model: bool = True
    every_frames: int = param(2, ge=1)
    candidates: int = param(12, ge=1)
    regions_in_radius: bool = True
    min_region_area_ratio: float = param(0.05, gt=0, le=1)
    detection: DetectionConfig = field(
        default_factory=lambda: DetectionConfig(grow_k=0.0, background_samples=13)
    )


@dataclass(frozen=True)
class DeciderConfig(Section):
    """The dual tracker's decision: which cue's measurement a target takes in a frame.

    The rules themselves are :class:`pipeline.trackers.dual.decide.Rule`, in order; these are
    their thresholds.

    Parameters
    ----------
    psr_confident : float
        A correlation-filter detection is a measurement when its peak-to-sidelobe ratio
        reaches this, >= 0; default 7. Increasing it trusts the filter less often.
    psr_update : float
        The filter learns only from frames whose detection reaches this PSR, >= 0; default 6.
    psr_reacquire : float
        A hidden target is taken back by the filter alone at this PSR, >= 0; default 9.
    weak_psr_fraction : float
        A coasting target whose filter peak reaches this share of ``psr_confident`` is still
        partly seen (``occluded-partial`` rather than ``occluded-severe``), in [0, 1];
        default 0.5.
    agree_fraction : float
        Two cues agree when their centres are within this share of the target's size on each
        axis, in (0, 2]; default 0.35.
    jump_fraction : float
        A tracked target's measurement lies within this share of its size (on each axis) of
        its prediction or of its last box; one farther is not taken, in (0, 5]; default 0.75.
    jump_sigma : float
        Around the prediction, that reach grows by this many standard deviations of the
        predicted centre (per axis), >= 0; default 3. A target whose motion is not yet known
        (its first frames, or after it was found again) may move by more than a share of its
        size: a 10 px wide person walking 8 px a frame; once its motion is known the
        prediction's deviation shrinks to a few px and the reach to about ``jump_fraction``.
    jump_speed : float
        Around the last box, that reach grows by this many times the target's recent speed (px
        a frame over its clean measurements), >= 0; default 1. A target that turns or stops
        ends up to one frame's travel from where it was, which the prediction (ahead by that
        much) does not cover once its deviation has shrunk; 0 keeps the reach at
        ``jump_fraction`` of the size.
    colour_min_rho : float
        A colour match under this contradicts a measurement at that place, in [0, 1];
        default 0.6.
    colour_veto_margin : float
        Where the colour is seen, a contour or a filter detection whose colour match is under
        ``colour_min_rho`` is not taken when the mean shift matches this much better
        elsewhere, in (0, 1]; default 0.2.
    colour_deny_rho : float
        After every target's own decision, a target whose measurement lies mostly inside
        another's (``inside_fraction`` of its area) and whose colour matches there under this
        yields to the other (a frame-level step, as ``shared_iou``), in [0, 1]; default 0.35
        (0: off). A small target's filter can follow a part of a larger neighbour, confident,
        long after its colour stopped matching; alone in the frame the same low match may be
        the target's own colour changing, so nothing is refused there. Raising it makes a
        target yield on a weaker doubt, a small one in front of a large one included.
    inside_fraction : float
        With ``colour_deny_rho``: the share of a measurement's area inside another target's
        that makes it lie on that target, in (0, 1]; default 0.6.
    overlap_freezes : bool
        A target whose measured box overlaps another target's box this frame (the paper's
        eq. 10 merge test on the two) teaches its models nothing from the frame: the filter's
        window and the colour histogram would hold the other target's pixels (the paper's
        merged members do not learn either); default True. False lets each learn through the
        overlap; a long walk side by side then adapts to the pair.
    background_share : float
        Where a still camera's IR background of the sequence is known, a filter detection whose
        box differs from it in under this share of its pixels, and whose colour does not
        confirm it (a match under ``colour_min_rho``, or no colour), is not confident: the box
        has slid onto the background, in [0, 1]; default 0.05 (0: off). A target standing
        still long enough to enter the background estimate is refused too when its colour is
        not seen; raising it refuses targets that differ little from their background (a cold
        target at night).
    visible_carries_psr : float
        The background test reads the IR frame only. A tracked target measured cleanly on the
        frame before, whose filter detection peaks at this PSR in the visible channel and under
        ``psr_reacquire`` in the IR, is not refused by it: the IR does not see this target (a
        cool body against a warm wall, a dimmed colour in a shadow), so the IR background
        cannot tell it from the background, and the visible channel carries it, >= 0; default
        12 (0: off). A target found again after a gap is not spared: a cold look-alike is
        seen the same way. Lowering it spares weaker visible peaks, a look-alike's included.
    occlusion_rho : float
        A colour match this strong carries a target whose IR has faded, in [0, 1]; default
        0.75.
    colour_trust_rho : float
        A colour match this strong carries a target with no other measurement, in [0, 1];
        default 0.85; 1 never.
    whole_colour_rho : float
        A colour match this strong at the filter's box says the whole target is there: a
        contour that collapsed under it is the infrared's failure (a target near the ground's
        temperature), not a part hidden: the target is reported ``tracking`` instead of
        ``occluded-partial`` and its models learn from the frame, unless another target is
        within half a box of it (the colour cannot tell that one from this one). The frame still
        counts as partial evidence: the colour extent does not widen the box (nothing in the
        infrared bounds it) and the motion holds as for a hidden part; in [0, 1], default 0.9:
        on the development seeds it is reached on 46 % (one target) and 31 % (2-3 targets) of
        the fully visible target-frames whose contour collapsed, and on 2-3 % of the partly
        hidden ones. 1: every collapse is a partial occlusion (models frozen).
    partial_area_ratio : float
        A contour box under this share of the target's usual box is cut by something in
        front (the target is partially occluded), in (0, 1); default 0.6.
    reacquire_rho : float
        A hidden target is taken back by colour only when the match reaches this, in [0, 1];
        default 0.7.
    reacquire_gate_px_per_frame : float
        A hidden target is taken back near its prediction: within half its size plus this
        many px per missing frame, >= 0; default 1 (re-detection by the filter widens it).
    noise_scale_contour : float
        The Kalman measurement noise of a contour measurement, as a multiple of the
        ``kalman`` section's, > 0; default 1.
    noise_scale_appearance : float
        The same for a filter detection, > 0; default 1.5 (its box follows the filter's
        template, which lags a change of shape).
    noise_scale_colour : float
        The same for a mean-shift position, > 0; default 2 (the kernel's centre of colour
        mass, not of the target).
    shared_iou : float
        Two targets whose measurements overlap by at least this IoU have found one object:
        one decision over both gives it to the better match (:meth:`Decider.owner_of`), and
        the other is ``merged`` with it, keeping to its own motion (its prediction lies on
        that object too), or coasts, hidden (``Rule.SHARED``); in [0, 1]; default 0, off:
        both take it. At 0.5 it lifts the mean many-target purity of two development samples
        by 0.006 but lowers the 10th percentile of one of them and the named group3's purity
        (0.982 -> 0.963): a member that yielded is not told apart again when the two part
        (CHANGELOG).
    shared_colour_margin : float
        Between two targets that both held their object last frame (else the one that did
        keeps it), the better match of a shared measurement is the one whose colour model
        matches its own box there more closely by at least this (Bhattacharyya coefficient);
        closer than that, or without colour, the one whose prediction lies nearer (in its own
        sizes), in [0, 1]; default 0.05.
    turn_search : bool
        Where the filter is not confident at the prediction (under ``psr_confident``), it
        also looks where a stop or a reversal would have taken the target: at its last clean
        measurement and as far behind it as the prediction is ahead (:meth:`Decider.turns`);
        default True. Costs two detections on such frames.
    reach_missing : bool
        A missing target is also taken back by a filter detection at ``psr_reacquire`` where
        it can have got to since its last clean measurement (``jump_fraction`` of its size plus
        ``jump_speed`` times its recent speed per frame since, around that measurement) and
        the colour does not say it is elsewhere (from the re-detection search, which tries many
        places, only with a colour match of ``colour_deny_rho``; :meth:`View.reached`);
        default True. Without
        it, only near the prediction (``reacquire_gate_px_per_frame``) or found by the
        re-detection search with a colour match of ``reacquire_rho``: a target that turned
        while coasting is seen and refused.
    redetect_local_margin : float
        A missing target is not taken back by a find of the re-detection search away from
        where the mean shift, near the prediction, matches its colour better by at least this
        (the target is likelier still there, unseen by the filter, than at a look-alike
        elsewhere), in [0, 1]; default 0.05; 1 never refuses.
    corroborate_psr : float
        A missing target is also taken back, however far from its prediction and however low
        its colour match, by a filter detection of at least this PSR that the colour's own
        search found too (the mean shift's centre within ``agree_fraction`` of its size),
        whose peak reaches ``psr_reacquire`` in each channel the filter reads, that overlaps no
        other target's box, where no other target's colour model matches better than its own,
        and that differs from a still camera's background (``background_share``;
        ``Rule.APPEARANCE_AND_COLOUR``), >= 0; default 12 (0: off). With one channel it needs
        that background's test or a clean contour on the find (infrared alone): on visible
        footage alone it never applies, since a look-alike fools the colour and the gradients
        of one image. Two cues that agree outvote the motion: a fast target that turned while
        it coasted, or whose colour a shadow dimmed under ``reacquire_rho``, is taken back where
        both find it. A cold look-alike has no infrared peak and a background structure does
        not differ from the background; another person of like colours and heat is taken
        (development range: 24 of 25 such finds within 20 px of the target with one target, 9
        of 11 with 2-3, the other two on another target or a passer-by).
    """

    section = "decider"

    psr_confident: float = param(7.0, ge=0)
    psr_update: float = param(6.0, ge=0)
    psr_reacquire: float = param(9.0, ge=0)
    weak_psr_fraction: float = param(0.5, ge=0, le=1)
    agree_fraction: float = param(0.35, gt=0, le=2)
    jump_fraction: float = param(0.75, gt=0, le=5)
    jump_sigma: float = param(3.0, ge=0)
    jump_speed: float = param(1.0, ge=0)
    colour_min_rho: float = param(0.6, ge=0, le=1)
    colour_veto_margin: float = param(0.2, gt=0, le=1)
    colour_deny_rho: float = param(0.35, ge=0, le=1)
    inside_fraction: float = param(0.6, gt=0, le=1)
    overlap_freezes: bool = True
    background_share: float = param(0.05, ge=0, le=1)
    visible_carries_psr: float = param(12.0, ge=0)
    occlusion_rho: float = param(0.75, ge=0, le=1)
    colour_trust_rho: float = param(0.85, ge=0, le=1)
    whole_colour_rho: float = param(0.9, ge=0, le=1)
    partial_area_ratio: float = param(0.6, gt=0, lt=1)
    reacquire_rho: float = param(0.7, ge=0, le=1)
    reacquire_gate_px_per_frame: float = param(1.0, ge=0)
    noise_scale_contour: float = param(1.0, gt=0)
    noise_scale_appearance: float = param(1.5, gt=0)
    noise_scale_colour: float = param(2.0, gt=0)
    shared_iou: float = param(0.0, ge=0, le=1)
    shared_colour_margin: float = param(0.05, ge=0, le=1)
    turn_search: bool = True
    reach_missing: bool = True
    redetect_local_margin: float = param(0.05, ge=0, le=1)
    corroborate_psr: float = param(12.0, ge=0)


@dataclass(frozen=True)
class SizeConfig(Section):
    """The dual tracker's size: how the box's width and height follow the cues.

    Parameters
    ----------
    scale_rate : float
        a_s of eq. 7: the weight of a measured size in the size update, in [0, 1]; default
        0.2. Increasing it follows size changes faster and passes measurement noise on.
    scale_agree_ratio : float
        A contour whose width or height differs from the filter's size by more than this
        factor is not used for the size, and the size stays within this factor of the
        filter's, > 1; default 1.25.
    contour_contrast_ratio : float
        A contour's size enters the update only where its contrast is at least this many
        times ``contour.min_contrast``, >= 1; default 2 (a faint contour's box is loose).
    """

    section = "size"

    scale_rate: float = param(0.2, ge=0, le=1)
    scale_agree_ratio: float = param(1.25, gt=1)
    contour_contrast_ratio: float = param(2.0, ge=1)


@dataclass(frozen=True)
class LifecycleConfig(Section):
    """The dual tracker's lifecycle: when a hidden target is lost, and what ``conf`` says.

    Parameters
    ----------
    max_missing_frames : int
        Frames without a measurement before a target is reported lost, >= 1; default 50. A
        lost target is still searched for (``redetect``).
    confidence_tracking : float
        ``conf`` of a tracked target's row in tracks.csv, in [0, 1]; default 1.
    confidence_partial : float
        ``conf`` of a partly occluded one, in [0, 1]; default 0.6.
    confidence_severe : float
        ``conf`` of a severely occluded one (coasting on its motion), in [0, 1]; default 0.3.
    """

    section = "lifecycle"

    max_missing_frames: int = param(50, ge=1)
    confidence_tracking: float = param(1.0, ge=0, le=1)
    confidence_partial: float = param(0.6, ge=0, le=1)
    confidence_severe: float = param(0.3, ge=0, le=1)


@dataclass(frozen=True)
class GroupConfig(Section):
    """The dual tracker's group handling: targets in mutual occlusion (the paper's eq. 10-11).

    The eq. 10 merge test on the mean-shift positions joins targets into a group; one level set
    runs over the group's blob, started from the members' positions; each member is placed in
    it (``merge_position``) with status ``merged`` and no model learns; when the blob shows a
    component for every member, the group splits and the components are re-associated
    globally.

    Parameters
    ----------
    merge_position : str
        Where merged members are placed: ``eq11`` (the paper: the foreground at its mean
        shift, the other mirrored about the blob centre), ``motion`` (the foreground as in
        the paper, the others at their prediction) or ``auto`` (default: look-alikes by
        k-means on the blob, every member whose colour is clearly seen by its own mean shift,
        the rest by eq. 11 while the blob is wider than the foreground, else by motion).
    role_margin : float
        The foreground keeps its role until another member's colour match is higher by this,
        in [0, 1]; default 0.05.
    split_min_area_fraction : float
        A blob component counts as a separated target when its box covers this share of the
        smallest member's usual box, in (0, 1); default 0.3.
    association_motion_weight : float
        Weight of the distance to each prediction (in target sizes) against the colour
        dissimilarity when blobs are re-associated after a split, >= 0; default 1 (0 is the
        paper: colour only).
    lookalike_rho : float
        Two targets whose colour models match this well are look-alikes, in [0, 1]; default
        0.85.
    merge_visible_rho : float
        In ``auto``, a merged member whose colour match reaches this is placed by its own
        mean shift, in [0, 1]; default 0.75.
    inside_blob : bool
        A merged member placed on its motion state is reported inside the blob's box;
        default True.
    split_hold_frames : int
        For this many frames after a split, targets merge again only on a deep overlap
        (``remerge_scale``), >= 0; default 3.
    remerge_scale : float
        The merge test's half-sizes are scaled by this during that hold, in (0, 1]; default
        0.8.
    kmeans_iterations : int
        Passes of the k-means that places look-alikes in a blob, in [1, 50]; default 5.
    blob_cold_start_scale : float
        The group's level set starts cold from the union of the members' boxes times this, in
        [1, 2]; default 1.15.
    blob_max_ratio : float
        The group's contour is not refused as too large or misshapen below this multiple of
        the union's area and sides (it holds several targets), > 1; default 50.
    blob_margin_scale : float
        A component of the group's contour belongs to the group when it meets the union of
        the members' boxes grown this many times, >= 1; default 1.2.
    wider_ratio : float
        In ``auto``, the blob counts as wider than the foreground (eq. 11 places the other
        member) when its width exceeds the foreground's by this factor, >= 1; default 1.2.
    confidence_foreground : float
        ``conf`` of the group's foreground member in tracks.csv, in [0, 1]; default 0.7.
    confidence_hidden : float
        ``conf`` of the other members, in [0, 1]; default 0.4.
    """

    section = "groups"

    merge_position: str = param("auto", choices=("auto", "eq11", "motion"))
    role_margin: float = param(0.05, ge=0, le=1)
    split_min_area_fraction: float = param(0.3, gt=0, lt=1)
    association_motion_weight: float = param(1.0, ge=0)
    lookalike_rho: float = param(0.85, ge=0, le=1)
    merge_visible_rho: float = param(0.75, ge=0, le=1)
    inside_blob: bool = True
    split_hold_frames: int = param(3, ge=0)
    remerge_scale: float = param(0.8, gt=0, le=1)
    kmeans_iterations: int = param(5, ge=1, le=50)
    blob_cold_start_scale: float = param(1.15, ge=1, le=2)
    blob_max_ratio: float = param(50.0, gt=1)
    blob_margin_scale: float = param(1.2, ge=1)
    wider_ratio: float = param(1.2, ge=1)
    confidence_foreground: float = param(0.7, ge=0, le=1)
    confidence_hidden: float = param(0.4, ge=0, le=1)


@dataclass(frozen=True)
class DualConfig(Section):
    """The dual-channel tracker (``dual``), one section per part it is built from.

    ========================== ======================================================
    part                       sections
    ========================== ======================================================
    motion (Kalman)            ``motion``, ``kalman``
    colour cue (mean shift)    ``colour``, ``histogram``, ``meanshift``, ``model_update``
    contour cue (level set)    ``contour``, ``levelset``
    appearance cue (filter)    ``appearance`` (optional)
    colour extent              ``extent`` (optional)
    re-detector                ``redetect`` (optional; its ``detection``)
    decider                    ``decider``
    size                       ``size``
    lifecycle                  ``lifecycle``
    group handling (eq. 10-11) ``groups`` (optional)
    ========================== ======================================================

    The paper's method (Zhao, Bo, Yin 2012) is :meth:`paper` (``data/dual-paper.toml``): no
    filter, extent or re-detector, every contour taken, the search from the last position,
    and eq. 10-11 for targets in mutual occlusion.

    Parameters
    ----------
    motion : MotionConfig
        Where the searches start, and coasting.
    kalman : KalmanConfig
        The motion part's Kalman model.
    colour : ColourConfig
        When the colour cue runs and where it searches.
    histogram : HistogramConfig
        The colour cue's histogram binning.
    meanshift : MeanShiftConfig
        The colour cue's mean shift.
    model_update : ModelUpdateConfig
        The colour model's selective update (eq. 8-9).
    contour : ContourConfig
        The contour cue: region, starts and failure tests of the IR contour.
    levelset : LevelSetConfig
        The contour cue's DRLSE level set.
    appearance : AppearanceConfig or None
        Beyond the paper: a correlation filter over both channels measures position and
        size and decides where the contour and the colour disagree; None leaves it out.
    extent : ExtentConfig or None
        Beyond the paper: the box's width and height also follow the target's extent in its
        colours, each on its own, at ``size.scale_rate``; None leaves it out. A walking
        person's legs, a turning car or a cyclist change the box's aspect, which the
        filter's scale (one factor for both axes) cannot follow.
    redetect : RedetectConfig or None
        Beyond the paper: the search for a hidden or lost target; None leaves it out.
    decider : DeciderConfig
        The thresholds of the decision between the cues.
    size : SizeConfig
        How the box's size follows the cues (eq. 7).
    lifecycle : LifecycleConfig
        When a hidden target is lost; the confidence of each status.
    groups : GroupConfig or None
        The paper's handling of mutual occlusion (eq. 10-11: the merge test, one level set
        over the merged blob, the split and re-association; status ``merged``); default
        None: with the correlation filter every target keeps itself through a crossing
        better on its own.
    """

    section = "dual"

    motion: MotionConfig = field(default_factory=MotionConfig)
    kalman: KalmanConfig = field(default_factory=KalmanConfig)
    colour: ColourConfig = field(default_factory=ColourConfig)
    histogram: HistogramConfig = field(default_factory=HistogramConfig)
    meanshift: MeanShiftConfig = field(default_factory=MeanShiftConfig)
    model_update: ModelUpdateConfig = field(default_factory=ModelUpdateConfig)
    contour: ContourConfig = field(default_factory=ContourConfig)
    levelset: LevelSetConfig = field(default_factory=LevelSetConfig)
    appearance: AppearanceConfig | None = field(default_factory=AppearanceConfig)
    extent: ExtentConfig | None = field(default_factory=ExtentConfig)
    redetect: RedetectConfig | None = field(default_factory=RedetectConfig)
    decider: DeciderConfig = field(default_factory=DeciderConfig)
    size: SizeConfig = field(default_factory=SizeConfig)
    lifecycle: LifecycleConfig = field(default_factory=LifecycleConfig)
    groups: GroupConfig | None = None

    @classmethod
    def paper(cls) -> DualConfig:
        """The paper's dual tracker (Zhao, Bo, Yin 2012): every addition left out.

        Mean shift in the visible frame from the last position, the DRLSE contour (started
        cold, every contour taken) in the IR frame for position and size, eq. 7 for the
        scale, eq. 8-9 for the model, and eq. 10-11 for targets in mutual occlusion
        (re-association by colour alone). ``data/dual-paper.toml`` is the same
        configuration as a file.

        Examples
        --------
        >>> cfg = DualConfig.paper()
        >>> cfg.appearance is None, cfg.groups.merge_position, cfg.motion.search_from
        (True, 'eq11', 'last-position')
        """
        return cls(
            motion=MotionConfig(search_from="last-position", rewind_tolerance=0.0),
            colour=ColourConfig(dark_gating=False),
            contour=ContourConfig(
                checks=False,
                trust_faded=True,
                start_at="meanshift",
                warm_start=False,
                closing_fraction=0.0,
                retry_empty_frames=1,
            ),
            appearance=None,
            extent=None,
            redetect=None,
            decider=DeciderConfig(
                colour_trust_rho=1.0, colour_deny_rho=0.0, background_share=0.0, jump_speed=0.0
            ),
            groups=GroupConfig(
                merge_position="eq11",
                inside_blob=False,
                split_hold_frames=0,
                association_motion_weight=0.0,
            ),
        )


@dataclass(frozen=True)
class MeanShiftTrackerConfig(Section):
    """The ``meanshift`` tracker: kernel-weighted colour histogram mean shift with a scale
    search.

    Parameters
    ----------
    histogram : HistogramConfig
        The histogram binning.
    search : MeanShiftConfig
        The mean shift and its +-10 % scale search.
    """

    section = "meanshift"

    histogram: HistogramConfig = field(default_factory=HistogramConfig)
    search: MeanShiftConfig = field(default_factory=MeanShiftConfig)


@dataclass(frozen=True)
class CamShiftConfig(Section):
    """The classic CamShift peer (OpenCV sample recipe).

    Parameters
    ----------
    hue_bins : int
        Bins of the hue histogram (visible), in [2, 180]; default 16.
    intensity_bins : int
        Bins of the intensity histogram (infrared), in [2, 256]; default 16.
    min_saturation : int
        Pixels below this saturation are ignored in visible frames, in [0, 255]; default 60.
        Increasing it ignores more washed-out pixels.
    min_value : int
        Pixels below this brightness are ignored in visible frames, in [0, 255]; default 32.
    max_iterations : int
        Mean-shift iterations per frame, >= 1; default 10.
    epsilon_px : float
        Stop when the window moves less than this, px, > 0; default 1 (OpenCV rounds
        epsilon squared, so values below 0.5 never stop early).
    saturation_bins : int
        Saturation bins crossed with the hue bins in the back-projection of
        ``kalman-camshift``, in [1, 16]; default 4. 1 is the hue-only back-projection
        the paper and OpenCV's recipe use; hue alone cannot tell a brown wall from a
        shirt of its hue. The plain ``camshift`` peer always uses hue only.
    background_weighting_scale : float
        ``kalman-camshift``'s back-projected model is weighted against the target's
        surround (the corrected background-weighted histogram of Ning et al. 2012,
        :func:`pipeline.stages.camshift.background_weights`): the surround is a box this
        many times the target's, less the target's ellipse scaled 1.2 times, on the
        first frame; in [0, 5], default 2; 0 (and up to about 1.2, which leaves no
        surround) is the paper's unweighted model. Colours the
        target shares with its surround (trousers of the lawn's hue) then barely draw
        CamShift's window out of the target. Larger surrounds weigh down colours that
        are only far away. The plain ``camshift`` peer never weights.
    max_scale_step : float
        ``kalman-camshift`` measures a target's size from CamShift's window only as a scale of
        its last good box (the square root of their areas' ratio), changed by at most this
        fraction a frame, its aspect ratio kept, in [0, 1]; default 0.01. CamShift's moments
        shrink the window onto the part of a target whose colour the model holds best, and
        stretch it onto same-coloured surroundings, a frame at a time; a target that
        approaches or recedes changes its size steadily and slowly. Larger values follow fast
        approaches sooner and let the window's jitter and bias in; 1 measures CamShift's
        window as it is (the paper's). The plain ``camshift`` peer always takes the window.
    """

    section = "camshift"

    hue_bins: int = param(16, ge=2, le=180)
    intensity_bins: int = param(16, ge=2, le=256)
    min_saturation: int = param(60, ge=0, le=255)
    min_value: int = param(32, ge=0, le=255)
    max_iterations: int = param(10, ge=1)
    epsilon_px: float = param(1.0, gt=0)
    saturation_bins: int = param(4, ge=1, le=16)
    background_weighting_scale: float = param(2.0, ge=0, le=5)
    max_scale_step: float = param(0.01, ge=0, le=1)


@dataclass(frozen=True)
class OpenCVTrackerConfig(Section):
    """OpenCV's learning trackers (MIL, CSRT, KCF) used as peers.

    Parameters
    ----------
    channel : str
        Channel the peers run on in two-channel sequences, ``visible`` or ``infrared``;
        default ``visible`` (what people run them on today).
    """

    section = "opencv"

    channel: str = param("visible", choices=("visible", "infrared"))


@dataclass(frozen=True)
class KalmanCamShiftConfig(Section):
    """The ``kalman-camshift`` tracker (Yan et al. 2014): CamShift from a Kalman prediction,
    with graded occlusion.

    Parameters
    ----------
    channel : str
        Channel it runs on in two-channel sequences, ``visible`` or ``infrared``; default
        ``visible``.
    camshift : CamShiftConfig
        The CamShift search and its colour model.
    kalman : KalmanConfig
        The 12-state motion model.
    occlusion : OcclusionConfig
        The occlusion grading by Bhattacharyya distance and area.
    """

    section = "kalman_camshift"

    channel: str = param("visible", choices=("visible", "infrared"))
    camshift: CamShiftConfig = field(default_factory=CamShiftConfig)
    kalman: KalmanConfig = field(default_factory=KalmanConfig)
    occlusion: OcclusionConfig = field(default_factory=OcclusionConfig)


@dataclass(frozen=True)
class DetectConfig(Section):
    """The ``detect`` tracker: detection, Kalman prediction and global association (no
    initial boxes); also what ``dualtrack detect`` and ``track --detect`` run.

    Parameters
    ----------
    detection : DetectionConfig
        STDM / foreground detection and ROI discrimination (``split_core_fraction`` 0 here:
        touching regions are not split; the tracker keeps a blob that holds several tracks'
        predictions as their merged blob and places its members inside it).
    roi_match : RoiMatchConfig
        The affine-invariant ROI correlation (the image term of the association).
    association : AssociationConfig
        Global association, track birth and death.
    kalman : KalmanConfig
        The tracks' motion model (made constant-velocity with the association's noises).
    """

    section = "detect"

    detection: DetectionConfig = field(
        default_factory=lambda: DetectionConfig(split_core_fraction=0.0)
    )
    roi_match: RoiMatchConfig = field(default_factory=RoiMatchConfig)
    association: AssociationConfig = field(default_factory=AssociationConfig)
    kalman: KalmanConfig = field(default_factory=KalmanConfig)
