"""The dual tracker's parameters (``--set dual.<name>=...``)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class DualConfig:
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
        regions the STDM detector finds in the whole frame; default True.
    redetect_radius_px_per_frame : float
        The search region around a hidden target's prediction grows by this per missing
        frame, px, >= 0; default 3.
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

    scale_rate: float = 0.2
    appearance_cue: bool = True
    psr_confident: float = 7.0
    psr_update: float = 6.0
    psr_reacquire: float = 9.0
    agree_fraction: float = 0.35
    scale_agree_ratio: float = 1.25
    colour_veto_margin: float = 0.2
    jump_fraction: float = 0.75
    contour_checks: bool = True
    channel_weighting: bool = True
    motion_prior: bool = True
    redetect: bool = True
    redetect_radius_px_per_frame: float = 3.0
    redetect_global_after_frames: int = 12
    redetect_every_frames: int = 2
    redetect_candidates: int = 12
    colour_min_value: int = 40
    colour_min_fraction: float = 0.3
    colour_min_rho: float = 0.6
    occlusion_rho: float = 0.75
    colour_trust_rho: float = 0.85
    partial_area_ratio: float = 0.6
    reacquire_rho: float = 0.7
    reacquire_gate_px_per_frame: float = 1.0
    max_missing_frames: int = 50
    missing_search_scale: float = 2.0
    history_frames: int = 16
    rewind_frames: int = 8
    onset_frames: int = 4
    merge_handling: bool = False
    merge_position: str = "auto"
    role_margin: float = 0.05
    split_min_area_fraction: float = 0.3
    association_motion_weight: float = 1.0
    lookalike_rho: float = 0.85
    merge_visible_rho: float = 0.75
    merge_inside_blob: bool = True
    split_hold_frames: int = 3
    remerge_scale: float = 0.8
    kmeans_iterations: int = 5

    def __post_init__(self) -> None:
        def between(name: str, lo: float, hi: float, lo_open: bool = False, hi_open: bool = False) -> None:
            v = getattr(self, name)
            ok = (lo < v if lo_open else lo <= v) and (v < hi if hi_open else v <= hi)
            if not ok:
                lb, rb = "(" if lo_open else "[", ")" if hi_open else "]"
                raise ValueError(f"dual.{name} must be in {lb}{lo:g}, {hi:g}{rb}; got {v!r}")

        def integer(name: str, lo: int, hi: int | None = None) -> None:
            v = getattr(self, name)
            if not (isinstance(v, int) and v >= lo and (hi is None or v <= hi)):
                rng = f"in [{lo}, {hi}]" if hi is not None else f">= {lo}"
                raise ValueError(f"dual.{name} must be an integer {rng}; got {v!r}")

        for name in ("scale_rate", "colour_min_fraction", "colour_min_rho", "occlusion_rho", "colour_trust_rho",
                     "reacquire_rho", "lookalike_rho", "merge_visible_rho", "role_margin"):
            between(name, 0, 1)
        for name in ("psr_confident", "psr_update", "psr_reacquire", "reacquire_gate_px_per_frame",
                     "redetect_radius_px_per_frame", "association_motion_weight"):
            between(name, 0, float("inf"))
        between("agree_fraction", 0, 2, lo_open=True)
        between("colour_veto_margin", 0, 1, lo_open=True)
        between("jump_fraction", 0, 5, lo_open=True)
        between("scale_agree_ratio", 1, float("inf"), lo_open=True)
        between("colour_min_value", 0, 255)
        between("partial_area_ratio", 0, 1, lo_open=True, hi_open=True)
        between("split_min_area_fraction", 0, 1, lo_open=True, hi_open=True)
        between("missing_search_scale", 1, 5)
        between("remerge_scale", 0, 1, lo_open=True)
        integer("max_missing_frames", 1)
        integer("history_frames", 2, 100)
        integer("rewind_frames", 0, 30)
        integer("onset_frames", 0, 10)
        integer("kmeans_iterations", 1, 50)
        integer("split_hold_frames", 0)
        integer("redetect_global_after_frames", 1)
        integer("redetect_every_frames", 1)
        integer("redetect_candidates", 1)
        if self.merge_position not in ("auto", "eq11", "motion"):
            raise ValueError(f"dual.merge_position must be auto, eq11 or motion; got {self.merge_position!r}")
