"""The trackers' own parameters: ``dual``, ``camshift`` and ``opencv`` sections.

They live beside the stage sections (``pipeline.stages.*``) rather than in the trackers, so
that :mod:`pipeline.config` gathers every section without importing a tracker and the
trackers take the typed :class:`pipeline.config.PipelineConfig`.
"""

from __future__ import annotations

from dataclasses import dataclass

from pipeline.params import Section, param


@dataclass(frozen=True)
class DualConfig(Section):
    """The dual-channel tracker: what each cue may do, and when a target counts as hidden or gone.

    The paper's method (Zhao, Bo, Yin 2012) is the configuration with every addition off
    (``data/dual-paper.toml``): mean shift in the visible frame, the DRLSE contour in the IR
    frame for position and size, eq. 7 for the scale and eq. 8-9 for the model.

    Parameters
    ----------
    scale_rate : float
        a_s of eq. 7: the weight of the contour's size in the size update, in [0, 1]; default
        0.2. Increasing it follows size changes faster and passes contour noise on.
    appearance_cue : bool
        Beyond the paper: a correlation filter over both channels (``pipeline.stages.
        appearance``) measures position and size; it decides where the contour and the
        colour disagree; default True.
    extent_cue : bool
        Beyond the paper: the box's width and height also follow the target's extent in its
        colours (``pipeline.stages.extent``), each on its own, at ``scale_rate``; the size may
        then leave the filter's by up to ``extent.max_ratio`` per axis; default True. A walking
        person's legs, a turning car or a cyclist change the box's aspect, which the filter's
        scale (one factor for both axes) cannot follow.
    psr_confident : float
        A correlation-filter detection is a measurement when its peak-to-sidelobe ratio
        reaches this, >= 0; default 7. Increasing it trusts the filter less often.
    psr_update : float
        The filter learns only from frames whose detection reaches this PSR, >= 0; default 6.
    psr_reacquire : float
        A hidden target is taken back by the filter alone at this PSR, >= 0; default 9.
    agree_fraction : float
        The contour and the filter agree when their centres are within this share of the
        target's size on each axis, in (0, 2]; default 0.35.
    scale_agree_ratio : float
        A contour whose width or height differs from the filter's size by more than this
        factor is not used for the size, > 1; default 1.25.
    jump_fraction : float
        A tracked target's measurement lies within this share of its size (on each axis) of
        its prediction or of its last box; one farther is not taken, in (0, 5]; default 0.75.
    jump_sigma : float
        Around the prediction, that reach grows by this many standard deviations of the
        predicted centre (per axis), >= 0; default 3. A target whose motion is not yet known
        (its first frames, or after it was found again) may move by more than a share of its
        size: a 10 px wide person walking 8 px a frame; once its motion is known the
        prediction's deviation shrinks to a few px and the reach to about ``jump_fraction``.
    colour_veto_margin : float
        Where the colour is seen, a contour or a filter detection whose colour match is under
        ``colour_min_rho`` is not taken when the mean shift matches this much better
        elsewhere, in (0, 1]; default 0.2.
    contour_checks : bool
        Beyond the paper: a contour that leaks, collapses, grows too large, changes shape or
        loses its contrast is not a measurement; default True (False uses any contour, as
        the paper does).
    channel_weighting : bool
        Beyond the paper: skip the colour cue in dark frames and distrust a faded contour;
        default True.
    motion_prior : bool
        Beyond the paper: a Kalman prediction starts every search, carries hidden targets
        and gates their re-acquisition; default True (False starts from the last position).
    redetect : bool
        Beyond the paper: a hidden or lost target is searched for by its filter in a region
        that widens while it is missing and, after ``redetect_global_after_frames``, at the
        regions the detector (``detection`` section) finds in the whole frame; default True.
    redetect_radius_px_per_frame : float
        The search region around a hidden target's prediction grows by this per missing
        frame, px, >= 0; default 3.
    redetect_last_seen : bool
        The widening search region lies around the hidden target's last clean measurement as
        well as around its prediction (the candidates shared between the two), and widens at
        the target's recent speed where that exceeds ``redetect_radius_px_per_frame``, so that
        a target that turned or stopped while hidden is found where it was; default True.
    redetect_global_after_frames : int
        Missing frames after which the whole frame is searched, >= 1; default 12.
    redetect_every_frames : int
        A missing target is searched for every this many frames, >= 1; default 2.
    redetect_candidates : int
        At most this many places are tried by one search, >= 1; default 12 (a larger region
        is covered over successive searches). The cost of a search grows with it.
    colour_min_value : int
        Visible pixels darker than this (HSV value) carry no colour, in [0, 255]; default 40.
    colour_min_fraction : float
        The colour cue runs when at least this share of the kernel's pixels is bright enough,
        in [0, 1]; default 0.3.
    colour_min_rho : float
        A colour match under this contradicts a measurement at that place, in [0, 1];
        default 0.6.
    occlusion_rho : float
        A colour match this strong carries a target whose IR has faded, in [0, 1]; default 0.75.
    colour_trust_rho : float
        A colour match this strong carries a target with no other measurement, in [0, 1];
        default 0.85; 1 never.
    partial_area_ratio : float
        A contour box under this share of the target's usual box is cut by something in
        front (the target is partially occluded), in (0, 1); default 0.6.
    reacquire_rho : float
        A hidden target is taken back by colour only when the match reaches this, in [0, 1];
        default 0.7.
    reacquire_gate_px_per_frame : float
        A hidden target is taken back near its prediction: within half its size plus this
        many px per missing frame, >= 0; default 1 (re-detection by the filter widens it).
    max_missing_frames : int
        Frames without a measurement before a target is reported lost, >= 1; default 50. A
        lost target is still searched for (``redetect``).
    missing_search_scale : float
        While a target is missing, its colour search region is this many times larger, in
        [1, 5]; default 2.
    history_frames : int
        Clean measurements kept for the coasting line fit, in [2, 100]; default 16.
    rewind_frames : int
        The coast restarts from that fit if its newest measurement is at most this old, in
        [0, 30]; default 8; 0 never.
    onset_frames : int
        The newest measurements left out of that fit (an occluder may have been cutting them
        already), in [0, 10]; default 4.
    merge_handling : bool
        Handle mutual occlusion as the paper does (eq. 10 merge test, foreground and occluded
        roles, one level set over the merged blob, split and re-association; status
        ``merged`` and the merge and split events); default False: with the correlation
        filter every target keeps itself through a crossing better on its own (True is the
        paper's, and ``data/dual-paper.toml`` sets it).
    merge_position : str
        Where merged members are placed: ``eq11`` (the paper: the foreground at its mean
        shift, the other mirrored about the blob centre), ``motion`` (the foreground as in
        the paper, the others at their prediction) or ``auto`` (default: look-alikes by
        k-means on the blob, every member whose colour is clearly seen by its own mean shift,
        the rest by eq. 11 while the blob is wider than the foreground, else by motion).
    lookalike_rho : float
        Two targets whose colour models match this well are look-alikes, in [0, 1]; default 0.85.
    merge_visible_rho : float
        In ``auto``, a merged member whose colour match reaches this is placed by its own
        mean shift, in [0, 1]; default 0.75.
    merge_inside_blob : bool
        A merged member placed on its motion state is reported inside the blob's box;
        default True.
    split_hold_frames : int
        For this many frames after a split, targets merge again only on a deep overlap
        (``remerge_scale``), >= 0; default 3.
    remerge_scale : float
        The merge test's half-sizes are scaled by this during that hold, in (0, 1]; default 0.8.
    kmeans_iterations : int
        Passes of the k-means that places look-alikes in a blob, in [1, 50]; default 5.
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
    """

    section = "dual"

    scale_rate: float = param(0.2, ge=0, le=1)
    appearance_cue: bool = True
    extent_cue: bool = True
    psr_confident: float = param(7.0, ge=0)
    psr_update: float = param(6.0, ge=0)
    psr_reacquire: float = param(9.0, ge=0)
    agree_fraction: float = param(0.35, gt=0, le=2)
    scale_agree_ratio: float = param(1.25, gt=1)
    colour_veto_margin: float = param(0.2, gt=0, le=1)
    jump_sigma: float = param(3.0, ge=0)
    jump_fraction: float = param(0.75, gt=0, le=5)
    contour_checks: bool = True
    channel_weighting: bool = True
    motion_prior: bool = True
    redetect: bool = True
    redetect_radius_px_per_frame: float = param(3.0, ge=0)
    redetect_last_seen: bool = True
    redetect_global_after_frames: int = param(12, ge=1)
    redetect_every_frames: int = param(2, ge=1)
    redetect_candidates: int = param(12, ge=1)
    colour_min_value: int = param(40, ge=0, le=255)
    colour_min_fraction: float = param(0.3, ge=0, le=1)
    colour_min_rho: float = param(0.6, ge=0, le=1)
    occlusion_rho: float = param(0.75, ge=0, le=1)
    colour_trust_rho: float = param(0.85, ge=0, le=1)
    partial_area_ratio: float = param(0.6, gt=0, lt=1)
    reacquire_rho: float = param(0.7, ge=0, le=1)
    reacquire_gate_px_per_frame: float = param(1.0, ge=0)
    max_missing_frames: int = param(50, ge=1)
    missing_search_scale: float = param(2.0, ge=1, le=5)
    history_frames: int = param(16, ge=2, le=100)
    rewind_frames: int = param(8, ge=0, le=30)
    onset_frames: int = param(4, ge=0, le=10)
    merge_handling: bool = False
    merge_position: str = param("auto", choices=("auto", "eq11", "motion"))
    role_margin: float = param(0.05, ge=0, le=1)
    split_min_area_fraction: float = param(0.3, gt=0, lt=1)
    association_motion_weight: float = param(1.0, ge=0)
    lookalike_rho: float = param(0.85, ge=0, le=1)
    merge_visible_rho: float = param(0.75, ge=0, le=1)
    merge_inside_blob: bool = True
    split_hold_frames: int = param(3, ge=0)
    remerge_scale: float = param(0.8, gt=0, le=1)
    kmeans_iterations: int = param(5, ge=1, le=50)


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
