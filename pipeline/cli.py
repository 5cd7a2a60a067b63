"""``dualtrack`` command line (also ``python -m pipeline``).

Exit status: 0 success; 1 bad input or a failed run (one line on stderr, no traceback);
130 interrupted (the outputs for the frames done are valid). Set ``DUALTRACK_DEBUG=1``
to see the traceback of an unexpected error.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

PROG = "dualtrack"


_ESCAPES = {c: f"\\x{c:02x}" for c in [*range(32), 127]} | {10: "\\n", 13: "\\r", 9: "\\t"}


def one_line(text: object) -> str:
    """``text`` on one line: control characters (a newline in a folder's name) escaped as Python
    writes them (``\\n``)."""
    return str(text).translate(_ESCAPES)


def _say(text: str) -> None:
    """``dualtrack: <text>`` on stderr, on one line."""
    print(f"{PROG}: {one_line(text)}", file=sys.stderr)


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line, exit 1 (docs/formats.md), not argparse's 2
        self.exit(1, f"{PROG}: error: {one_line(message)} (see {self.prog} --help)\n")

    def add_argument(self, *args: Any, **kwargs: Any) -> argparse.Action:
        """As argparse's, and a name or path given as an empty string is refused (``--out ''``
        would write into the current folder, ``--tracker=`` run the default)."""
        takes_text = kwargs.get("type", str) in (str, Path) and "choices" not in kwargs
        if takes_text and kwargs.get("action", "store") in ("store", "append"):
            kwargs["type"] = _non_empty(kwargs.get("type", str))
        return super().add_argument(*args, **kwargs)


def _non_empty(convert: Callable[[str], Any]) -> Callable[[str], Any]:
    def text(value: str) -> Any:
        if not value.strip():
            raise argparse.ArgumentTypeError("an empty value; give one or leave the option out")
        return convert(value)

    return text


def _add_open_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--channel",
        choices=("visible", "infrared"),
        help=(
            "what a one-channel folder holds (default: grey = infrared); in a two-channel "
            "folder, use only this channel"
        ),
    )
    p.add_argument(
        "--align",
        choices=("none", "resize"),
        default="none",
        help="'resize' scales infrared frames to the visible size when they differ",
    )
    p.add_argument(
        "--gt-base",
        type=float,
        default=None,
        metavar="B",
        help="coordinate base of the ground-truth files (0 or 1; default per layout)",
    )


def _add_config_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--config",
        type=Path,
        help="TOML file of parameters, tables along the tree ([dual.decider], [detect.detection])",
    )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="PATH.PARAM=VALUE",
        help=(
            "override one parameter (dual.decider.psr_confident=8; dual.groups=none leaves a "
            "part out); repeatable, after --config"
        ),
    )


def _add_protocol(p: argparse.ArgumentParser, what: str) -> None:
    from pipeline.eval.protocols import PROTOCOLS

    p.add_argument(
        "--protocol",
        choices=PROTOCOLS,
        default="default",
        help=f"the rules of {what}: ours (default) or a toolkit's own (docs/formats.md)",
    )


def build_parser() -> argparse.ArgumentParser:
    from pipeline._version import __version__

    parser = _Parser(prog=PROG, description="Tracking in registered infrared + visible video.")
    parser.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    p = sub.add_parser("track", help="track targets through a sequence folder")
    p.add_argument(
        "seq_dir",
        type=Path,
        help="a sequence folder of any layout docs/formats.md lists (frames and any truth)",
    )
    p.add_argument("--out", type=Path, help="run folder (default runs/<sequence name>)")
    p.add_argument("--tracker", default=None, help="tracker engine (see 'dualtrack trackers')")
    p.add_argument(
        "--init", action="append", metavar="X,Y,W,H", help="initial box (repeatable; ids 1..N)"
    )
    p.add_argument("--init-file", type=Path, help="file of x,y,w,h lines or MOT rows of frame 1")
    p.add_argument("--detect", action="store_true", help="find the initial targets automatically")
    p.add_argument(
        "--associator",
        choices=("hungarian", "chnn"),
        default=None,
        help="data association of --tracker detect (same as --set detect.association.associator=)",
    )
    _add_config_options(p)
    p.add_argument("--no-rrd", action="store_true", help="do not write run.rrd")
    p.add_argument("--no-plots", action="store_true", help="do not write plots/")
    _add_protocol(p, "the evaluation in summary.json")
    p.add_argument("--force", action="store_true", help="overwrite a non-empty run folder")
    p.add_argument("--frames", type=int, default=None, metavar="N", help="stop after N frames")
    p.add_argument(
        "--decode-scale",
        choices=("auto", "1", "2", "4", "8"),
        default="auto",
        help=(
            "track on frames read at 1/N of their size, boxes written at full size (JPEG "
            "decoded there by libjpeg); 'auto' (default): large JPEG frames with large targets"
        ),
    )
    _add_open_options(p)

    p = sub.add_parser("evaluate", help="score a results file against a sequence's ground truth")
    p.add_argument("seq_dir", type=Path, help="the sequence folder, with its ground truth")
    p.add_argument(
        "tracks_csv",
        type=Path,
        help="results: MOTChallenge rows (tracks.csv of a run folder) or one x,y,w,h per frame",
    )
    p.add_argument("--json", action="store_true", help="print the metrics as one JSON object")
    p.add_argument(
        "--results-base",
        type=float,
        default=None,
        metavar="B",
        help="coordinate base of the results file (0 or 1; default 1 for MOT rows, 0 for one "
        "x,y,w,h per frame)",
    )
    _add_protocol(p, "the scores")
    p.add_argument(
        "--mot-rule",
        choices=("trackeval", "motmetrics"),
        default="trackeval",
        help="CLEAR matching of the many-target scores: TrackEval's (the MOTChallenge numbers) or "
        "py-motmetrics' (a match carried across gaps)",
    )
    p.add_argument(
        "--ids",
        choices=("auto", "truth", "assign"),
        default="auto",
        help=(
            "score each truth id against the track with its id (truth), the IDF1 assignment's "
            "track (assign, for detection-made ids), or truth when every track id is a truth id "
            "(auto)"
        ),
    )
    _add_open_options(p)

    p = sub.add_parser(
        "detect", help="STDM detection on every frame: det.txt, rois.csv, detections.rrd"
    )
    p.add_argument(
        "seq_dir",
        type=Path,
        help="a sequence folder of any layout docs/formats.md lists (frames and any truth)",
    )
    p.add_argument(
        "--out", type=Path, required=True, help="output folder: det.txt, rois.csv, summary.json"
    )
    p.add_argument("--no-rrd", action="store_true", help="do not write detections.rrd")
    p.add_argument("--force", action="store_true", help="overwrite a non-empty output folder")
    _add_config_options(p)
    _add_open_options(p)

    p = sub.add_parser("synth", help="write synthetic sequences with exact ground truth")
    p.add_argument(
        "name",
        nargs="?",
        help="scenario name (see --list), or 'random' for a scene drawn from the seed",
    )
    p.add_argument(
        "out_dir", nargs="?", type=Path, help="the sequence folder to write (with --all: a root)"
    )
    p.add_argument(
        "--list", action="store_true", help="print the scenarios, one per line, name first"
    )
    p.add_argument("--all", action="store_true", help="write every scenario into OUT_DIR/<name>/")
    p.add_argument(
        "--seed",
        type=int,
        default=0,
        help="sensor noise of a named scene; the whole scene of 'random' (0-999 development, "
        "1000-1999 test)",
    )
    p.add_argument(
        "--seeds",
        default=None,
        metavar="A-B",
        help="random: one scene per seed A..B (inclusive) into OUT_DIR/random-<seed>/",
    )
    p.add_argument(
        "--targets",
        default=None,
        metavar="K|A-B",
        help="random: number of targets, or a range to draw it from (default drawn 1-3)",
    )
    p.add_argument(
        "--size", default="320x240", metavar="WxH", help="random: frame size (default 320x240)"
    )
    p.add_argument(
        "--frames",
        type=int,
        default=200,
        metavar="N",
        help="random: sequence length (default 200)",
    )
    p.add_argument("--ir16", action="store_true", help="random: write 16-bit infrared PNGs")
    p.add_argument("--force", action="store_true", help="overwrite existing sequence folders")

    p = sub.add_parser(
        "bench", help="compare trackers on sequences: accuracy and speed on one core"
    )
    p.add_argument(
        "seq_dirs", type=Path, nargs="*", help="sequence folders to run every tracker on"
    )
    p.add_argument(
        "--targets",
        default=None,
        metavar="N,N,...",
        help="instead of sequences: fps vs number of targets on synthetic scenes (e.g. 1,2,4,8)",
    )
    p.add_argument("--trackers", default=None, help="comma-separated tracker names")
    p.add_argument("--json", type=Path, help="also write the table as JSON")
    p.add_argument(
        "--out", type=Path, help="keep the run folders here (default: a temporary folder)"
    )
    p.add_argument(
        "--repeat",
        type=int,
        default=1,
        metavar="N",
        help="time every run N times and keep the fastest (default 1)",
    )
    p.add_argument(
        "--random",
        type=int,
        default=None,
        metavar="N",
        help=(
            "instead of sequences: N random scenes of the --split, and the distribution of "
            "the scores"
        ),
    )
    p.add_argument(
        "--split",
        choices=("test", "dev"),
        default="test",
        help=(
            "random scenes: 'test' seeds (only ever scored, the default) or 'dev' seeds (for "
            "tuning)"
        ),
    )
    p.add_argument(
        "--seeds",
        default=None,
        metavar="A-B",
        help="random scenes: these seeds instead of a split",
    )
    p.add_argument(
        "--random-targets",
        default=None,
        metavar="K|A-B",
        help="random scenes: number of targets per scene (default drawn 1-3)",
    )
    _add_config_options(p)
    _add_open_options(p)

    p = sub.add_parser(
        "batch", help="run every sequence under a folder (locally or on Dask) and write one report"
    )
    p.add_argument("root", type=Path, help="archive root: every sequence folder under it is run")
    p.add_argument(
        "--out",
        type=Path,
        required=True,
        help="one run folder per sequence, report.json/.md, plots/",
    )
    p.add_argument(
        "--trackers",
        default=None,
        help="comma-separated tracker names (default: the default tracker)",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        help="sequences at a time on this machine (default: cores)",
    )
    p.add_argument(
        "--scheduler",
        default=None,
        metavar="tcp://HOST:PORT",
        help="run on a Dask distributed cluster",
    )
    p.add_argument(
        "--ship-frames",
        action="store_true",
        help=(
            "with --scheduler: send each sequence's files to the worker (default: workers "
            "read ROOT's path)"
        ),
    )
    p.add_argument(
        "--force", action="store_true", help="redo sequences whose run folder is complete"
    )
    _add_protocol(p, "every run and the report's aggregation")
    p.add_argument(
        "--export",
        choices=("rgbt234", "gtot", "lasher", "vtuav", "mot"),
        default=None,
        help="also write each tracker's results in that toolkit's format (mot: the "
        "MOTChallenge / TrackEval folder layout, gt/ and trackers/NAME/data/SEQ.txt)",
    )
    p.add_argument(
        "--timeout",
        type=float,
        default=None,
        metavar="SECONDS",
        help="a sequence taking longer fails",
    )
    p.add_argument("--no-rrd", action="store_true", help="do not write run.rrd per sequence")
    p.add_argument("--no-plots", action="store_true", help="do not write plots/ per sequence")
    p.add_argument(
        "--frames", type=int, default=None, metavar="N", help="stop every run after N frames"
    )
    _add_config_options(p)
    _add_open_options(p)

    sub.add_parser("trackers", help="list the tracker engines and whether they can run here")
    return parser


def _cmd_track(a: argparse.Namespace) -> int:
    from pipeline.run import RunOptions, run_track
    from pipeline.trackers import DEFAULT_TRACKER

    res = run_track(
        a.seq_dir,
        RunOptions(
            tracker=a.tracker or DEFAULT_TRACKER,
            out_dir=a.out,
            init=a.init,
            init_file=a.init_file,
            detect=a.detect,
            channel=a.channel,
            align=a.align,
            gt_base=a.gt_base,
            config_path=a.config,
            sets=a.set
            + ([f"detect.association.associator={a.associator}"] if a.associator else []),
            rrd=not a.no_rrd,
            plots=not a.no_plots,
            protocol=a.protocol,
            force=a.force,
            stop_frame=a.frames,
            decode_scale=None if a.decode_scale == "auto" else int(a.decode_scale),
        ),
    )
    s = res.summary
    _warn(s.get("warnings"))
    line = (
        f"{res.out_dir}: {s['frames']}/{s['frames_total']} frames, {s['tracker']}, "
        f"fps_tracking {s['fps_tracking']}"
    )
    if int(s.get("decode_scale") or 1) > 1:
        line += f", read at 1/{s['decode_scale']} size"
    m = s.get("metrics")
    if isinstance(m, dict):
        parts = [
            f"{k} {m[k]:.3f}"
            for k in ("p20", "auc", "mpr", "msr", "pr", "sr", "mota", "idf1")
            if isinstance(m.get(k), float)
        ]
        line += ", " + ", ".join(parts)
    print(line)
    if res.crash is not None and os.environ.get("DUALTRACK_DEBUG"):
        raise res.crash
    return _ending(res.error, res.interrupted, int(s["frames"]), res.out_dir)


def _warn(warnings: object) -> None:
    for w in warnings if isinstance(warnings, list) else []:
        _say(f"warning: {w}")


def _ending(error: str | None, interrupted: bool, frames: int, out: Path) -> int:
    """The exit status of a run, with its one line on stderr (the run loop kept every output
    valid)."""
    if error:
        if not out.is_dir():
            _say(f"error: the run folder {out} was removed during the run, after {frames} frames")
        else:
            _say(f"error: {error} (the outputs in {out} hold the first {frames} frames)")
        return 1
    if interrupted:
        _say(f"interrupted after {frames} frames; outputs in {out} are valid")
        return 130
    return 0


def _cmd_evaluate(a: argparse.Namespace) -> int:
    import json

    from pipeline.eval import evaluate_files

    m = evaluate_files(
        a.seq_dir,
        a.tracks_csv,
        a.protocol,
        a.ids,
        a.mot_rule,
        a.results_base,
        channel=a.channel,
        align=a.align,
        gt_base=a.gt_base,
    )
    _warn(m.get("warnings"))
    if a.json:
        print(json.dumps(m))
        return 0
    keys = [
        k
        for k in (
            "p5",
            "p20",
            "auc",
            "mean_error_px",
            "npr",
            "mpr",
            "msr",
            "pr",
            "sr",
            "mota",
            "motp",
            "idf1",
            "idf1_visible",
            "purity_visible",
            "id_switches",
            "hota",
        )
        if k in m
    ]
    for k in keys:
        v = m[k]
        print(f"{k:>14}  {v:.4f}" if isinstance(v, float) else f"{k:>14}  {v}")
    return 0


def parse_size(text: str) -> tuple[int, int]:
    """``WxH`` -> (W, H) in px."""
    from pipeline.errors import InputError

    w, sep, h = text.lower().partition("x")
    if not sep or not w.isdigit() or not h.isdigit():
        raise InputError(f"--size must be WxH in px, e.g. 320x240; got {text!r}")
    return int(w), int(h)


def _cmd_synth_random(a: argparse.Namespace) -> int:
    from pipeline.errors import InputError
    from pipeline.progress import Progress
    from pipeline.synthetic import synthesize_random
    from pipeline.synthetic.family import parse_seed_range, parse_target_count

    if a.out_dir is None:
        raise InputError("synth random needs OUT_DIR")
    try:
        targets = parse_target_count(a.targets)
        seeds = parse_seed_range(a.seeds) if a.seeds is not None else None
    except ValueError as exc:
        raise InputError(str(exc)) from None
    size = parse_size(a.size)
    if seeds is None:
        path = synthesize_random(a.out_dir, a.seed, targets, size, a.frames, a.ir16, a.force)
        print(f"wrote {path}")
        return 0
    with Progress(len(seeds), "synth random", unit="scenes") as bar:
        for seed in seeds:
            synthesize_random(
                a.out_dir / random_folder_name(seed),
                seed,
                targets,
                size,
                a.frames,
                a.ir16,
                a.force,
                progress=False,
            )
            bar.update(1)
    print(
        f"wrote {len(seeds)} random scenes (seeds {seeds.start}-{seeds.stop - 1}) into {a.out_dir}"
    )
    return 0


def random_folder_name(seed: int) -> str:
    """Folder name of a random scene in a set: ``random-0042``."""
    return f"random-{seed:04d}"


def _cmd_synth(a: argparse.Namespace) -> int:
    from pipeline.errors import InputError
    from pipeline.synthetic import SCENARIOS, synthesize

    if a.list:
        print(
            "random  a whole scene drawn from the seed: background, targets, paths, events, "
            "sensor (--seed, --seeds A-B)"
        )
        for name, sc in SCENARIOS.items():
            print(f"{name}  {sc.description}")
        return 0
    if a.seed < 0:
        raise InputError(f"--seed must be a non-negative integer; got {a.seed}")
    if a.name == "random":
        return _cmd_synth_random(a)
    if a.seeds is not None or a.targets is not None or a.ir16:
        raise InputError("--seeds, --targets and --ir16 apply to 'synth random' only")
    if a.all:
        out = a.out_dir if a.out_dir is not None else (Path(a.name) if a.name else None)
        if out is None:
            raise InputError("synth --all needs OUT_DIR")
        names = list(SCENARIOS)
        for name in names:
            synthesize(name, out / name, seed=a.seed, force=a.force)
        print(f"wrote {len(names)} sequences into {out}")
        return 0
    if not a.name or a.out_dir is None:
        raise InputError("synth needs NAME OUT_DIR (or --list, or --all OUT_DIR)")
    path = synthesize(a.name, a.out_dir, seed=a.seed, force=a.force)
    print(f"wrote {path}")
    return 0


def _cmd_bench(a: argparse.Namespace) -> int:
    import json

    from pipeline.bench import format_table, run_bench
    from pipeline.errors import InputError

    trackers = [t.strip() for t in (a.trackers or "").split(",") if t.strip()] or None
    if a.trackers is not None and not trackers:
        raise InputError(f"--trackers names no tracker: {a.trackers!r}")
    if a.json is not None and a.json.is_dir():
        raise InputError(f"--json {a.json} is a folder; give a file name")
    if a.repeat < 1:
        raise InputError(f"--repeat must be an integer >= 1; got {a.repeat}")
    if a.random is not None or a.seeds is not None:
        from pipeline.bench import format_distribution, run_random_bench
        from pipeline.synthetic.family import parse_seed_range, parse_target_count

        if a.seq_dirs or a.targets:
            raise InputError(
                "bench --random/--seeds runs on generated scenes: give no sequence folders or "
                "--targets"
            )
        try:
            seeds = parse_seed_range(a.seeds) if a.seeds is not None else None
            targets = parse_target_count(a.random_targets)
        except ValueError as exc:
            raise InputError(str(exc)) from None
        res = run_random_bench(
            a.random,
            a.split,
            seeds,
            targets,
            trackers,
            out=a.out,
            json_path=a.json,
            sets=a.set,
            config_path=a.config,
            repeat=a.repeat,
            channel=a.channel,
        )
        print(format_distribution(res))
        return 0
    if a.targets:
        from pipeline.bench import format_scaling, run_scaling

        if a.channel is not None:
            raise InputError(
                "--channel applies to sequence folders and --random scenes, not to --targets"
            )

        try:
            counts = [int(v) for v in a.targets.split(",") if v.strip()]
        except ValueError:
            raise InputError(
                f"--targets takes comma-separated integers; got {a.targets!r}"
            ) from None
        rows = run_scaling(
            counts, trackers, out=a.out, sets=a.set, config_path=a.config, repeat=a.repeat
        )
        if a.json:
            a.json.write_text(json.dumps({"rows": rows}, indent=2) + "\n")
        print(format_scaling(rows))
        return 0
    if not a.seq_dirs:
        raise InputError(
            "bench needs sequence folders, or --targets N,N,... for the fps-vs-targets table"
        )
    rows = run_bench(
        a.seq_dirs,
        trackers,
        out=a.out,
        json_path=a.json,
        sets=a.set,
        config_path=a.config,
        repeat=a.repeat,
        channel=a.channel,
        align=a.align,
        gt_base=a.gt_base,
    )
    print(format_table(rows))
    failed = [r for r in rows if "failed" in r]
    if failed:
        first = failed[0]
        _say(
            f"error: {len(failed)} of {len(rows)} runs failed (listed above), the first "
            f"{first['sequence']}"
            + (f" / {first['tracker']}" if first["tracker"] != "-" else "")
            + f": {first['failed']}"
        )
        return 1
    return 0


def _cmd_batch(a: argparse.Namespace) -> int:
    from pipeline.batch import BatchOptions, run_batch
    from pipeline.trackers import DEFAULT_TRACKER

    trackers = tuple(t.strip() for t in (a.trackers or DEFAULT_TRACKER).split(",") if t.strip())
    from pipeline.errors import InputError

    if not trackers:
        raise InputError(f"--trackers names no tracker: {a.trackers!r}")
    if a.timeout is not None and not a.timeout > 0:
        raise InputError(f"--timeout must be a positive number of seconds; got {a.timeout:g}")
    if a.frames is not None and a.frames < 1:
        raise InputError(f"--frames must be at least 1; got {a.frames}")
    opts = BatchOptions(
        trackers=trackers,
        workers=a.workers,
        scheduler=a.scheduler,
        force=a.force,
        protocol=a.protocol,
        export=a.export,
        sets=tuple(a.set),
        config_path=a.config,
        rrd=not a.no_rrd,
        plots=not a.no_plots,
        ship_frames=a.ship_frames,
        timeout_s=a.timeout,
        channel=a.channel,
        align=a.align,
        gt_base=a.gt_base,
        stop_frame=a.frames,
    )
    res = run_batch(a.root, a.out, opts)
    n = {st: sum(r.status == st for r in res.results) for st in ("done", "skipped", "failed")}
    print(
        f"{res.out_dir}: {n['done']} done, {n['skipped']} already complete, {n['failed']} failed "
        f"in {res.wall_seconds:.1f} s; report in {res.out_dir / 'report.md'}"
    )
    if res.interrupted:
        _say(f"interrupted; finished sequences and the report in {res.out_dir} are valid")
        return 130
    if n["failed"]:
        first = next(r for r in res.results if r.status == "failed")
        _say(
            f"error: {n['failed']} of {len(res.results)} sequences failed, the first "
            f"{first.task.key}: {first.error} (all in {res.out_dir / 'report.md'})"
        )
        return 1
    return 0


def _cmd_detect(a: argparse.Namespace) -> int:
    from pipeline.detect_run import run_detect

    res = run_detect(
        a.seq_dir,
        a.out,
        a.set,
        a.config,
        rrd=not a.no_rrd,
        force=a.force,
        channel=a.channel,
        align=a.align,
        gt_base=a.gt_base,
    )
    s = res.summary
    _warn(s.get("warnings"))

    def f(key: str, nd: int) -> str:
        v = s.get(key)
        return f"{v:.{nd}f}" if isinstance(v, int | float) else "n/a"

    line = (
        f"{res.out_dir}: {s['frames']} frames, {f('detections_per_frame', 2)} detections per "
        "frame, "
        f"{f('ms_per_frame', 3)} ms per frame"
    )
    if s.get("background_seconds"):
        line += f" (and {f('background_seconds', 2)} s for the sequence's background)"
    if "targets_scored" in s:
        line += (
            f", recall {f('recall', 3)}, precision {f('precision', 3)} "
            f"({s['targets_scored']} visible targets)"
        )
    print(line)
    return _ending(res.error, res.interrupted, int(s["frames"]), res.out_dir)


def _cmd_trackers(_a: argparse.Namespace) -> int:
    from pipeline.trackers import DEFAULT_TRACKER, available_trackers, tracker_names

    ok = set(available_trackers())
    for n in tracker_names():
        note = "default" if n == DEFAULT_TRACKER else ""
        if n not in ok:
            note = "needs opencv-contrib (not installed)"
        print(f"{n:16s} {note}".rstrip())
    return 0


COMMANDS = {
    "track": _cmd_track,
    "evaluate": _cmd_evaluate,
    "synth": _cmd_synth,
    "bench": _cmd_bench,
    "batch": _cmd_batch,
    "detect": _cmd_detect,
    "trackers": _cmd_trackers,
}


def _die_with_parent() -> None:
    """A batch's child (``DUALTRACK_DIE_WITH_PARENT=<batch pid>``) asks Linux for a SIGTERM when
    the batch dies, so a killed batch leaves no orphan: the run loop then closes its outputs as on
    Ctrl-C."""
    parent = os.environ.get("DUALTRACK_DIE_WITH_PARENT")
    if not parent or not sys.platform.startswith("linux"):
        return
    try:
        import ctypes
        import signal

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, int(signal.SIGTERM), 0, 0, 0)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return
    if str(os.getppid()) != parent:  # the batch died before the request took effect
        raise SystemExit(130)


def main(argv: list[str] | None = None, hold: bool = False) -> int:
    """Run one ``dualtrack`` command line (``argv``, default ``sys.argv[1:]``); returns the exit
    status (module doc). ``hold`` keeps the signal handlers installed after it returns (the
    command's own process); otherwise the caller's are restored."""
    from pipeline._signals import Interrupts

    interrupts = Interrupts()
    interrupts.install()
    try:
        code = _main(argv)
        if code != 130 and interrupts.count:  # an interruption Python dropped on the way
            raise KeyboardInterrupt
        return code
    except Exception:
        if not interrupts.count:
            raise
        # a signal during an import can surface as another error (NumPy reports an
        # interrupted import of ``datetime`` as an ImportError): the interruption is the news
        _say("interrupted")
        return 130
    except KeyboardInterrupt:
        _say("interrupted")
        return 130
    finally:
        if not hold:
            interrupts.restore()


def _main(argv: list[str] | None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    _die_with_parent()
    # the Rerun SDK logs its own errors to stderr (a full disk twice over); ours name the file in
    # one line
    os.environ.setdefault("RUST_LOG", "off")
    if argv and argv[0] == "bench":  # one core, before numpy/OpenCV start their thread pools
        for var in (
            "OMP_NUM_THREADS",
            "OPENBLAS_NUM_THREADS",
            "MKL_NUM_THREADS",
            "NUMBA_NUM_THREADS",
        ):
            os.environ[var] = "1"
    parser = build_parser()
    a = parser.parse_args(argv)
    from pipeline._signals import taken

    try:
        return COMMANDS[a.command](a)
    except KeyboardInterrupt:
        _say("interrupted")
        return 130
    except BrokenPipeError:
        return 1
    except Exception as exc:
        if taken():
            raise  # what followed a signal: main says interrupted
        return _report(exc)


def _report(exc: Exception) -> int:
    """One line on stderr for a command's error (the exit status is 1): bad input and refused
    files as ``error:``, anything else as ``internal error:`` (``DUALTRACK_DEBUG=1`` re-raises
    it for the traceback)."""
    from pipeline.errors import InputError, describe_os_error

    if isinstance(exc, InputError):
        _say(f"error: {exc}")
    elif isinstance(exc, OSError):  # a file or folder the system refused: say which and why
        _say(f"error: {describe_os_error(exc)}")
    elif os.environ.get("DUALTRACK_DEBUG"):
        raise exc
    else:
        text = " ".join(str(exc).split())  # one line, whatever the exception's message holds
        _say(
            f"internal error: {type(exc).__name__}: {text} (set DUALTRACK_DEBUG=1 for the "
            "traceback)"
        )
    return 1


if __name__ == "__main__":
    raise SystemExit(main())
