"""The CLI's contract: one line and exit 1 for every bad input, 130 when interrupted, valid
outputs."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from pipeline.cli import main
from pipeline.synthetic import ONE_TARGET_SCENES
from tests.conftest import write_boxes, write_frames, write_pair
from tests.rrd_helpers import boxes_at, open_store, rows


def _run(argv, capsys):
    rc = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


def _tiny(root: Path, n: int = 6) -> Path:
    return write_pair(root, n)


def _assert_one_line_error(rc, err, match):
    assert rc == 1
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith("dualtrack: error: ") and match in lines[0], lines[0]
    assert "Traceback" not in err


def test_missing_folder(tmp_path, capsys):
    rc, _, err = _run(["track", tmp_path / "nope", "--out", tmp_path / "o"], capsys)
    _assert_one_line_error(rc, err, "sequence folder not found")


def test_unrecognised_layout(tmp_path, capsys):
    (tmp_path / "s" / "whatever").mkdir(parents=True)
    rc, _, err = _run(["track", tmp_path / "s", "--out", tmp_path / "o"], capsys)
    _assert_one_line_error(rc, err, "looked for: rgbt234")


def test_frame_counts_differ(tmp_path, capsys):
    write_frames(tmp_path / "s" / "visible", 4)
    write_frames(tmp_path / "s" / "infrared", 3, color=False)
    rc, _, err = _run(
        ["track", tmp_path / "s", "--init", "10,10,10,10", "--out", tmp_path / "o"], capsys
    )
    _assert_one_line_error(rc, err, "different frame counts")


def test_frame_sizes_differ(tmp_path, capsys):
    write_frames(tmp_path / "s" / "visible", 3, size=(64, 48))
    write_frames(tmp_path / "s" / "infrared", 3, size=(60, 48), color=False)
    rc, _, err = _run(
        ["track", tmp_path / "s", "--init", "10,10,10,10", "--out", tmp_path / "o"], capsys
    )
    _assert_one_line_error(rc, err, "different frame sizes: visible 64x48")


def test_malformed_truth(tmp_path, capsys):
    root = _tiny(tmp_path / "s")
    (root / "visible.txt").write_text("10,10,10,10\n11;10;10\n")
    rc, _, err = _run(["track", root, "--out", tmp_path / "o"], capsys)
    _assert_one_line_error(rc, err, "visible.txt:2: malformed ground truth")


def test_init_outside_frame(tmp_path, capsys):
    rc, _, err = _run(
        ["track", _tiny(tmp_path / "s"), "--init", "500,10,10,10", "--out", tmp_path / "o"], capsys
    )
    _assert_one_line_error(rc, err, "lies outside the 64x48 frame")
    assert not (tmp_path / "o").exists()  # nothing written for a run that cannot start


def test_empty_sequence(tmp_path, capsys):
    (tmp_path / "s" / "visible").mkdir(parents=True)
    (tmp_path / "s" / "infrared").mkdir(parents=True)
    rc, _, err = _run(["track", tmp_path / "s", "--out", tmp_path / "o"], capsys)
    _assert_one_line_error(rc, err, "empty sequence")


def test_unknown_tracker(tmp_path, capsys):
    rc, _, err = _run(
        ["track", _tiny(tmp_path / "s"), "--tracker", "nosuch", "--out", tmp_path / "o"], capsys
    )
    _assert_one_line_error(rc, err, "unknown tracker 'nosuch'; available: ")


def test_bad_set_and_bad_option(tmp_path, capsys):
    rc, _, err = _run(
        [
            "track",
            _tiny(tmp_path / "s"),
            "--set",
            "meanshift.search.max_iterations=-1",
            "--out",
            tmp_path / "o",
        ],
        capsys,
    )
    _assert_one_line_error(rc, err, "meanshift.search.max_iterations")
    with pytest.raises(SystemExit) as ex:
        main(["track", "--no-such-option"])
    assert ex.value.code == 1


def test_existing_run_folder_needs_force(tmp_path, capsys):
    root = _tiny(tmp_path / "s")
    assert _run(["track", root, "--tracker", "meanshift", "--out", tmp_path / "o"], capsys)[0] == 0
    rc, _, err = _run(["track", root, "--tracker", "meanshift", "--out", tmp_path / "o"], capsys)
    _assert_one_line_error(rc, err, "--force")
    assert (
        _run(
            ["track", root, "--tracker", "meanshift", "--out", tmp_path / "o", "--force"], capsys
        )[0]
        == 0
    )


def test_unreadable_frame_mid_run_keeps_results(tmp_path, capsys):
    root = _tiny(tmp_path / "s", n=8)
    (root / "visible" / "00006.jpg").write_bytes(b"\xff\xd8 broken")
    out = tmp_path / "o"
    rc, _stdout, err = _run(["track", root, "--tracker", "meanshift", "--out", out], capsys)
    _assert_one_line_error(rc, err, "unreadable frame 6")
    tracks = (out / "tracks.csv").read_text().splitlines()
    assert [int(r.split(",")[0]) for r in tracks] == [1, 2, 3, 4, 5]
    summary = json.loads((out / "summary.json").read_text())
    assert (
        summary["complete"] is False
        and summary["frames"] == 5
        and "unreadable frame 6" in summary["error"]
    )
    t = rows(open_store(out / "run.rrd"), "/visible/targets", ["Boxes2D:centers"])
    assert sorted(set(t["frame"].to_pylist())) == [1, 2, 3, 4, 5]


def test_evaluate_json(tmp_path, capsys):
    root = _tiny(tmp_path / "s")
    res = tmp_path / "res.txt"
    res.write_text(
        "\n".join(f"{10 + i},10,10,10" for i in range(6)) + "\n"
    )  # a per-frame box file
    rc, out, _ = _run(["evaluate", root, res, "--json"], capsys)
    assert rc == 0
    m = json.loads(out)
    assert m["p20"] == 1.0 and m["auc"] == pytest.approx(20 / 21) and m["mpr"] == 1.0
    rc, out, _ = _run(["evaluate", root, res, "--json", "--protocol", "lasher"], capsys)
    assert json.loads(out)["pr"] == 1.0


def test_synth_list(capsys):
    rc, out, _ = _run(["synth", "--list"], capsys)
    names = [ln.split()[0] for ln in out.splitlines()]
    assert rc == 0 and len(names) >= 8
    for required in (*ONE_TARGET_SCENES, "crossing2", "crossing3", "meet-part"):
        assert required in names
    assert len(ONE_TARGET_SCENES) == 8


def test_console_script_and_module_agree(tmp_path):
    for cmd in ([sys.executable, "-m", "pipeline", "trackers"], ["dualtrack", "trackers"]):
        exe = cmd[0] if cmd[0] != "dualtrack" else str(Path(sys.executable).parent / "dualtrack")
        p = subprocess.run([exe, *cmd[1:]], capture_output=True, text=True, timeout=120)
        assert p.returncode == 0 and "meanshift" in p.stdout


def _long_sequence(root: Path, n: int = 400) -> Path:
    rng = np.random.default_rng(0)
    for ch in ("visible", "infrared"):
        (root / ch).mkdir(parents=True)
    for i in range(n):
        img = rng.integers(40, 90, (240, 320, 3), dtype=np.uint8)
        x = 40 + (i % 200)
        img[100:160, x : x + 30] = (40, 40, 200)
        cv2.imwrite(str(root / "visible" / f"{i + 1:05d}v.jpg"), img)
        cv2.imwrite(str(root / "infrared" / f"{i + 1:05d}i.jpg"), img[..., 2])
    (root / "init.txt").write_text("40,100,30,60\n")
    return root


def test_ctrl_c_leaves_valid_outputs(tmp_path):
    root = _long_sequence(tmp_path / "s")
    out = tmp_path / "o"
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    p = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "pipeline",
            "track",
            str(root),
            "--tracker",
            "mil",
            "--out",
            str(out),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    deadline = time.time() + 120
    while time.time() < deadline:
        f = out / "tracks.csv"
        if f.exists() and len(f.read_text().splitlines()) >= 15:
            break
        time.sleep(0.1)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 130, err
    assert "Traceback" not in err and "interrupted" in err
    summary = json.loads((out / "summary.json").read_text())
    n = summary["frames"]
    assert summary["complete"] is False and 15 <= n < 400
    assert len((out / "tracks.csv").read_text().splitlines()) == n
    assert len((out / "targets.csv").read_text().splitlines()) == n + 1
    verify = subprocess.run(
        [str(Path(sys.executable).parent / "rerun"), "rrd", "verify", str(out / "run.rrd")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert verify.returncode == 0, verify.stderr
    store = open_store(out / "run.rrd")
    assert boxes_at(store, "/visible/targets", n) is not None


def test_synth_random_one_and_a_set(tmp_path, capsys):
    rc, _, _ = _run(["synth", "random", tmp_path / "one", "--seed", "4", "--frames", "30"], capsys)
    assert rc == 0 and (tmp_path / "one" / "scene.json").is_file()
    rc, _out, _ = _run(
        [
            "synth",
            "random",
            tmp_path / "set",
            "--seeds",
            "5-6",
            "--frames",
            "30",
            "--targets",
            "2",
        ],
        capsys,
    )
    assert rc == 0 and sorted(p.name for p in (tmp_path / "set").iterdir()) == [
        "random-0005",
        "random-0006",
    ]
    assert (
        len(json.loads((tmp_path / "set" / "random-0005" / "scene.json").read_text())["targets"])
        == 2
    )
    for argv, match in (
        (["synth", "random", tmp_path / "x", "--seed", "-1"], "non-negative"),
        (["synth", "random", tmp_path / "x", "--targets", "9"], "--targets"),
        (["synth", "random", tmp_path / "x", "--size", "big"], "--size"),
        (["synth", "crossing2", tmp_path / "x", "--seeds", "1-2"], "synth random"),
    ):
        rc, _, err = _run(argv, capsys)
        _assert_one_line_error(rc, err, match)


def test_visible_only_rgbt234_folder_runs(tmp_path, capsys):
    write_frames(tmp_path / "s" / "visible", 8)
    write_boxes(tmp_path / "s" / "visible.txt", 8)
    rc, _out, err = _run(["track", tmp_path / "s", "--out", tmp_path / "run", "--no-rrd"], capsys)
    assert rc == 0, err
    s = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert s["channels"] == ["visible"] and s["frames"] == 8 and s["metrics"]["p20"] == 1.0


def test_the_progress_bar_shows_one_rate_and_the_time_left():
    import io

    from pipeline.progress import Progress

    out = io.StringIO()
    with Progress(100, "dual s", enabled=True, stream=out) as p:
        for _ in range(100):
            p.update(1)
    last = out.getvalue().rstrip().split("\r")[-1]
    assert "100/100" in last and last.count("/s") == 1 and "left" in last


def test_every_argument_of_every_command_says_what_it_is():
    import argparse

    from pipeline.cli import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    silent = [
        f"{name} {a.dest}"
        for name, p in sub.choices.items()
        for a in p._actions
        if not isinstance(a, argparse._HelpAction) and not a.help
    ]
    assert not silent, silent
