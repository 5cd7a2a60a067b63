"""Faults a user meets, run as a user would (the CLI in a subprocess): every one leaves valid
outputs.

After each, ``summary.json`` says how many frames ``tracks.csv`` and ``targets.csv`` hold, the CSVs
end with a whole row, and the recording verifies (a SIGKILLed run's recording lacks its footer but
a stream reader reads every frame the CSVs hold).
"""

from __future__ import annotations

import csv
import json
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import write_pair

PY = sys.executable


def _cli(*args: object, timeout: float = 120) -> subprocess.CompletedProcess:
    """Run the CLI; one that hangs fails the test with every thread's Python stack (faulthandler on
    SIGABRT)."""
    cmd = [PY, "-X", "faulthandler", "-m", "pipeline", *map(str, args)]
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        out, err = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        p.send_signal(signal.SIGABRT)
        try:
            out, err = p.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            p.kill()
            out, err = p.communicate()
        pytest.fail(
            f"{' '.join(map(str, args))} still running after {timeout:.0f} s; its "
            f"stacks:\n{err[-6000:]}"
        )
    return subprocess.CompletedProcess(cmd, p.returncode, out, err)


def _start(*args: object) -> subprocess.Popen:
    return subprocess.Popen(
        [PY, "-m", "pipeline", *map(str, args)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _one_error_line(err: str, *needles: str) -> str:
    lines = [
        ln for ln in err.splitlines() if ln.strip() and not ln.startswith("dualtrack: warning:")
    ]
    assert len(lines) == 1, err
    assert lines[0].startswith("dualtrack: error: "), lines[0]
    for n in needles:
        assert n in lines[0], (n, lines[0])
    return lines[0]


def _summary(run: Path) -> dict:
    return json.loads((run / "summary.json").read_text())


def _csv_frames(run: Path) -> int:
    """Frames in targets.csv (every row whole: each parses to the header's columns)."""
    text = (run / "targets.csv").read_text()
    assert text.endswith("\n")
    rows = list(csv.reader(text.splitlines()))
    assert all(len(r) == len(rows[0]) for r in rows)
    tracks = (run / "tracks.csv").read_text()
    assert tracks == "" or tracks.endswith("\n")
    frames = {int(r[0]) for r in rows[1:]}
    assert frames == set(range(1, len(frames) + 1))
    return len(frames)


def _verify(rrd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [str(Path(PY).parent / "rerun"), "rrd", "verify", str(rrd)],
        capture_output=True,
        text=True,
        timeout=120,
    )


def _rrd_frames(rrd: Path) -> set[int]:
    from tests.rrd_helpers import open_store, rows

    t = rows(open_store(rrd), "/visible/targets", ["Boxes2D:centers"])
    return set(t.column("frame").to_pylist())


def _tiny(root: Path, n: int = 12) -> Path:
    return write_pair(root, n)


@pytest.fixture(scope="module")
def long_scene(tmp_path_factory) -> Path:
    """A 400-frame random scene: long enough under MIL (a few tens of frames per second) to be
    stopped mid-run."""
    from pipeline.synthetic import synthesize_random

    return synthesize_random(
        tmp_path_factory.mktemp("long") / "seq", 3, targets=1, frames=400, progress=False
    )


def _wait_frames(run: Path, frames: int, proc: subprocess.Popen, timeout: float = 120) -> None:
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        assert proc.poll() is None, proc.communicate()
        try:
            if _summary(run)["frames"] >= frames:
                return
        except (OSError, ValueError, KeyError):
            pass
        time.sleep(0.05)
    raise AssertionError("the run did not get going")


def test_zero_byte_frame_names_frame_and_file_and_keeps_the_frames_before(tmp_path):
    seq = _tiny(tmp_path / "s")
    bad = seq / "infrared" / "00009.jpg"
    bad.write_bytes(b"")
    r = _cli("track", seq, "--out", tmp_path / "run")
    assert r.returncode == 1
    _one_error_line(r.stderr, "frame 9", str(bad), "empty")
    s = _summary(tmp_path / "run")
    assert s["frames"] == 8 == _csv_frames(tmp_path / "run") and s["complete"] is False
    assert (tmp_path / "run" / "plots" / "precision.png").is_file() and s["metrics"]["frames"] == 8
    assert _verify(tmp_path / "run" / "run.rrd").returncode == 0


def test_detect_on_frames_without_detections(tmp_path):
    root = tmp_path / "flat"
    (root / "visible").mkdir(parents=True)
    (root / "infrared").mkdir(parents=True)
    import cv2

    for i in range(1, 6):
        cv2.imwrite(str(root / "visible" / f"{i:05d}.jpg"), np.full((48, 64, 3), 90, np.uint8))
        cv2.imwrite(str(root / "infrared" / f"{i:05d}.jpg"), np.full((48, 64), 90, np.uint8))
    r = _cli("detect", root, "--out", tmp_path / "det")
    assert r.returncode == 0, r.stderr
    assert "0.00 detections per frame" in r.stdout
    s = _summary(tmp_path / "det")
    assert s["complete"] and s["frames"] == 5 and s["detections_per_frame"] == 0.0


def test_full_disk_leaves_whole_rows_and_a_true_summary(tmp_path, scene):
    mnt = tmp_path / "small"
    mnt.mkdir()
    if subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=600k", "tmpfs", str(mnt)], capture_output=True
    ).returncode:
        pytest.skip("cannot mount a small tmpfs here (needs root or a mount namespace)")
    try:
        run = mnt / "run"
        r = _cli("track", scene("crossing2"), "--out", run)
        assert r.returncode == 1
        _one_error_line(r.stderr, str(run))
        s = _summary(run)
        assert s["complete"] is False and "error" in s
        assert (
            s["frames"] == _csv_frames(run) and s["frames"] % 16 == 0
        )  # the last checkpoint that fitted
        assert f"hold the first {s['frames']} frames" in r.stderr
        # the recording is cut back to that checkpoint: whole messages, every frame the summary
        # reports and no more (without a footer, as after a kill: readable as a stream)
        assert _rrd_frames(run / "run.rrd") == set(range(1, s["frames"] + 1))
    finally:
        subprocess.run(["umount", str(mnt)], capture_output=True)


def test_closing_a_recording_whose_writer_is_stuck_does_not_wait_for_it(monkeypatch):
    """On a full disk the SDK's file writer can stay blocked, and its ``disconnect`` with it (seen
    in CI: a run that hit the full disk waited in ``disconnect`` past the test's 120 s). The sink
    gives it a bounded wait, then takes the SDK's exit handler off so that the exit does not
    wait for the same writer; a disconnect that returns is simply waited for."""
    import threading

    import rerun as rr

    from pipeline.sinks import rerun_sink

    release = threading.Event()

    class Stuck:
        def disconnect(self):
            release.wait(30)

    class Fine:
        disconnected = False

        def disconnect(self):
            self.disconnected = True

    off = []
    monkeypatch.setattr(rr, "unregister_shutdown", lambda: off.append(True))
    t0 = time.monotonic()
    assert rerun_sink.disconnect_within(Stuck(), 0.2) is False
    assert time.monotonic() - t0 < 5 and off == [True]
    release.set()
    fine = Fine()
    assert rerun_sink.disconnect_within(fine, 5.0) is True
    assert fine.disconnected and off == [True]


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_sigterm_and_ctrl_c_mid_run_close_every_output(tmp_path, long_scene, sig):
    run = tmp_path / "run"
    p = _start("track", long_scene, "--tracker", "mil", "--out", run)
    _wait_frames(run, 32, p)
    p.send_signal(sig)
    _out, err = p.communicate(timeout=120)
    assert p.returncode == 130, err
    s = _summary(run)
    assert s["complete"] is False and s.get("interrupted") is True
    assert 32 <= s["frames"] < 400 and s["frames"] == _csv_frames(run)
    assert _verify(run / "run.rrd").returncode == 0
    assert _rrd_frames(run / "run.rrd") == set(range(1, s["frames"] + 1))


def test_sigkill_leaves_a_summary_true_to_the_files(tmp_path, long_scene):
    run = tmp_path / "run"
    p = _start("track", long_scene, "--tracker", "mil", "--out", run)
    _wait_frames(run, 48, p)
    p.kill()
    p.communicate(timeout=60)
    s = _summary(run)
    assert s["complete"] is False and s["frames"] >= 48
    assert s["frames"] == _csv_frames(
        run
    )  # rows are written at the checkpoints summary.json records
    assert _verify(run / "run.rrd").returncode != 0  # no footer after a kill ...
    assert set(range(1, s["frames"] + 1)) <= _rrd_frames(
        run / "run.rrd"
    )  # ... but every frame the CSVs hold


def test_second_ctrl_c_during_finalisation_does_not_lose_the_summary(tmp_path, long_scene):
    run = tmp_path / "run"
    p = _start("track", long_scene, "--tracker", "mil", "--out", run)
    _wait_frames(run, 32, p)
    p.send_signal(signal.SIGINT)
    for _ in range(3):  # impatient: more Ctrl-C while the sinks close and the plots are drawn
        time.sleep(0.1)
        if p.poll() is None:
            p.send_signal(signal.SIGINT)
    p.communicate(timeout=120)
    assert p.returncode == 130
    s = _summary(run)
    assert (
        s.get("interrupted") is True
        and s["frames"] == _csv_frames(run)
        and s["metrics"] is not None
    )
    assert _verify(run / "run.rrd").returncode == 0


def _children(marker: str) -> list[int]:
    out = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                cmd = (d / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            except OSError:
                continue
            if marker in cmd and " track " in cmd:
                out.append(int(d.name))
    return out


@pytest.mark.skipif(
    not sys.platform.startswith("linux"), reason="parent-death signals are Linux's"
)
def test_a_killed_batch_leaves_no_orphan_and_a_report(tmp_path, long_scene):
    import shutil

    arch = tmp_path / "arch"
    _tiny(arch / "a", 6)
    shutil.copytree(long_scene, arch / "b")
    out = tmp_path / "out"
    p = _start("batch", arch, "--out", out, "--trackers", "mil", "--workers", "1")
    _wait_frames(out / "b", 16, p)
    assert _children(str(arch / "b"))
    p.kill()
    p.communicate(timeout=30)
    t0 = time.monotonic()
    while _children(str(arch / "b")) and time.monotonic() - t0 < 30:
        time.sleep(0.1)
    assert not _children(str(arch / "b")), "the batch's child outlived it"
    s = _summary(out / "b")  # the child was stopped with SIGTERM: its outputs closed
    assert s.get("interrupted") is True and s["frames"] == _csv_frames(out / "b")
    report = json.loads((out / "report.json").read_text())
    assert report["sequences"]["a"]["status"] == "done"


def test_batch_timeout_stops_the_child_with_sigterm_first(tmp_path, long_scene):
    import shutil

    arch = tmp_path / "arch"
    shutil.copytree(long_scene, arch / "b")
    out = tmp_path / "out"
    r = _cli("batch", arch, "--out", out, "--trackers", "mil", "--timeout", "8")
    assert r.returncode == 1
    report = json.loads((out / "report.json").read_text())
    assert "timed out" in report["sequences"]["b"]["error"]
    s = _summary(out / "b")
    assert s.get("interrupted") is True and s["frames"] == _csv_frames(out / "b") > 0
    assert _verify(out / "b" / "run.rrd").returncode == 0


@pytest.mark.parametrize(
    "args, needles",
    [
        (["--gt-base", "7"], ["--gt-base must be 0 or 1"]),
        (["--frames", "0"], ["--frames must be at least 1"]),
        (["--frames", "-5"], ["--frames must be at least 1"]),
        (["--init", "3,3,1,1"], ["too small to track", "1x1 px"]),
    ],
)
def test_rejected_track_options(tmp_path, args, needles):
    seq = _tiny(tmp_path / "s", 4)
    r = _cli("track", seq, "--out", tmp_path / "run", *args)
    _one_error_line(r.stderr, *needles)
    assert r.returncode == 1 and not (tmp_path / "run").exists()


def test_rejected_bench_batch_and_synth_options(tmp_path):
    seq = _tiny(tmp_path / "s", 4)
    (tmp_path / "folder").mkdir()
    cases = [
        (["bench", seq, "--trackers", ","], ["--trackers names no tracker"]),
        (["bench", seq, "--json", tmp_path / "folder"], ["is a folder"]),
        (
            ["batch", tmp_path, "--out", tmp_path / "o", "--timeout", "-1"],
            ["--timeout must be a positive"],
        ),
        (
            ["batch", tmp_path, "--out", tmp_path / "o2", "--set", "dual.nope=1"],
            ["unknown parameter dual.nope"],
        ),
        (["synth", "random", tmp_path / "x", "--seed", "-1"], ["non-negative"]),
        (["synth", "crossing2", seq / "visible.txt"], ["is not a folder"]),
        (["track", seq, "--config", tmp_path / "folder"], ["is a folder"]),
    ]
    for argv, needles in cases:
        r = _cli(*argv)
        assert r.returncode == 1, (argv, r.stderr)
        _one_error_line(r.stderr, *needles)
    assert not (tmp_path / "o2").exists()  # the bad --set stopped the batch before any sequence


def test_unreadable_inputs_name_the_file(tmp_path):
    seq = _tiny(tmp_path / "s", 4)
    toml = tmp_path / "bad.toml"
    toml.write_bytes(bytes(range(256)))
    r = _cli("track", seq, "--out", tmp_path / "run", "--config", toml)
    _one_error_line(r.stderr, str(toml), "not a TOML file")
    junk = tmp_path / "junk.csv"
    junk.write_bytes(np.random.default_rng(0).integers(0, 256, 4000, dtype=np.uint8).tobytes())
    r = _cli("evaluate", seq, junk)
    _one_error_line(r.stderr, str(junk))


def test_output_under_a_file_and_read_only_folders(tmp_path):
    seq = _tiny(tmp_path / "s", 4)
    afile = tmp_path / "afile"
    afile.write_text("x")
    r = _cli("track", seq, "--out", afile / "run")
    _one_error_line(r.stderr, "is a file")
    ro = tmp_path / "ro"
    ro.mkdir()
    if subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "ro,size=64k", "tmpfs", str(ro)], capture_output=True
    ).returncode:
        pytest.skip("cannot mount a read-only tmpfs here")
    try:
        r = _cli("track", seq, "--out", ro / "run")
        _one_error_line(r.stderr, str(ro / "run"), "Read-only")
    finally:
        subprocess.run(["umount", str(ro)], capture_output=True)


def test_row_count_mismatches_and_duplicate_results_are_warnings(tmp_path):
    seq = _tiny(tmp_path / "s", 6)
    (seq / "visible.txt").write_text("10,10,10,10\n" * 4)  # 4 rows for 6 frames
    res = tmp_path / "res.csv"
    res.write_text(
        "1,1,11,11,10,10,1,-1,-1,-1\n1,1,11,11,10,10,1,-1,-1,-1\n2,1,12,11,10,10,1,-1,-1,-1\n"
    )
    r = _cli("evaluate", seq, res, "--json")
    assert r.returncode == 0, r.stderr
    warnings = [ln for ln in r.stderr.splitlines() if ln.startswith("dualtrack: warning:")]
    assert any("4 rows for 6 frames" in w for w in warnings) and any(
        "duplicate (frame, id)" in w for w in warnings
    )


def test_bench_reports_failed_sequences_and_prints_the_rest(tmp_path):
    good = _tiny(tmp_path / "good", 5)
    bad = _tiny(tmp_path / "bad", 5)
    (bad / "visible" / "00003.jpg").write_bytes(b"")
    r = _cli("bench", bad, good, "--trackers", "meanshift")
    assert r.returncode == 1
    assert (
        "| good | meanshift |" in r.stdout and "1 failed:" in r.stdout and "00003.jpg" in r.stdout
    )
    _only_line(r.stderr, "1 of 2 runs failed", "bad", "00003.jpg")  # and says so on stderr


def _wait_until_our_code_runs(proc: subprocess.Popen, timeout: float = 60) -> None:
    """Return once the process has taken SIGTERM (``pipeline._entry`` takes SIGINT, then
    SIGTERM, before anything else runs): read from the kernel's caught-signal mask in
    ``/proc/PID/status``, so a loaded machine's slow interpreter start cannot make a signal
    arrive while it is still the operating system's. Where ``/proc`` is missing, a generous
    fixed wait stands in."""
    status = Path(f"/proc/{proc.pid}/status")
    if not status.exists():
        time.sleep(3.0)
        return
    bit = 1 << (signal.SIGTERM - 1)
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        assert proc.poll() is None, proc.communicate()
        m = re.search(r"^SigCgt:\s*([0-9a-fA-F]+)", status.read_text(), re.M)
        if m and int(m.group(1), 16) & bit:
            return
        time.sleep(0.001)
    raise AssertionError("the command never took SIGTERM")


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
@pytest.mark.parametrize("after_start_s", [0.0, 0.05, 0.3, 0.8])
def test_a_signal_from_the_first_instant_is_an_interruption(
    tmp_path, long_scene, sig, after_start_s
):
    """Ctrl-C or SIGTERM from the moment our code runs (importing, reading the sequence) or
    while tracking: one line, ``interrupted``, exit 130; never a traceback, never 143. (Before
    the interpreter has started, a signal is the operating system's: ``pipeline._entry``.)"""
    p = _start("track", long_scene, "--tracker", "mil", "--out", tmp_path / "run")
    _wait_until_our_code_runs(p)
    time.sleep(after_start_s)
    p.send_signal(sig)
    _out, err = p.communicate(timeout=120)
    assert p.returncode == 130, (p.returncode, err)
    assert "Traceback" not in err
    assert err.strip().splitlines()[-1].startswith("dualtrack: interrupted"), err


def test_init_file_of_random_bytes_names_the_file(tmp_path):
    bad = tmp_path / "init.bin"
    bad.write_bytes(bytes(range(256)) * 4)
    r = _cli("track", _tiny(tmp_path / "s"), "--init-file", bad, "--out", tmp_path / "o")
    assert r.returncode == 1
    _one_error_line(r.stderr, str(bad), "not a text file")


# --- issue 31, items 15-16: what used to be accepted without a word, and one line per error ---


def _only_line(err: str, *needles: str) -> str:
    """stderr is exactly one line, an error naming every needle."""
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("dualtrack: error: "), lines[0]
    for n in needles:
        assert n in lines[0], (n, lines[0])
    return lines[0]


@pytest.mark.parametrize(
    ("args", "option"),
    [
        (["--tracker=", "--out", "o"], "--tracker"),
        (["--out", ""], "--out"),
        (["--set", "", "--out", "o"], "--set"),
    ],
)
def test_an_empty_value_is_refused(tmp_path, args, option):
    seq = _tiny(tmp_path / "s", 4)
    r = _cli("track", seq, *args)
    assert r.returncode == 1 and not Path("o").exists()
    _only_line(r.stderr, f"argument {option}: an empty value")


@pytest.mark.parametrize(
    ("item", "needle"),
    [
        ("meanshift.search.max_iterations=99999999999999999999", "at most 2147483647"),
        ("dual.kalman.position_std_px=inf", "must be a finite number"),
        ("dual.kalman.position_std_px=nan", "must be a finite number"),
    ],
)
def test_numbers_no_parameter_takes_are_refused(tmp_path, item, needle):
    r = _cli("track", _tiny(tmp_path / "s", 4), "--set", item, "--out", tmp_path / "o")
    assert r.returncode == 1 and not (tmp_path / "o").exists()
    _only_line(r.stderr, item.split("=")[0], needle)


def test_semicolon_truth_reads_as_commas_and_an_empty_field_is_an_error(tmp_path):
    from pipeline.io.sequence import open_sequence

    a = _tiny(tmp_path / "a", 5)
    b = _tiny(tmp_path / "b", 5)
    for ch in ("visible", "infrared"):
        (b / f"{ch}.txt").write_text((a / f"{ch}.txt").read_text().replace(",", "; "))
    ta, tb = open_sequence(a).truth, open_sequence(b).truth
    assert np.array_equal(ta.boxes["visible"][1], tb.boxes["visible"][1])
    lines = (a / "visible.txt").read_text().splitlines()
    lines[2] = lines[2].replace(",", ",,", 1)
    (a / "visible.txt").write_text("\n".join(lines) + "\n")
    r = _cli("track", a, "--out", tmp_path / "o")
    assert r.returncode == 1
    _only_line(r.stderr, f"{a / 'visible.txt'}:3", "an empty field")


def test_duplicate_truth_rows_are_a_warning(tmp_path):
    seq = _tiny(tmp_path / "s", 4)
    (seq / "gt.txt").write_text(
        "1,1,10,10,10,10,1,1,1\n2,1,11,10,10,10,1,1,1\n2,1,30,10,10,10,1,1,1\n"
        "3,1,12,10,10,10,1,1,1\n4,1,13,10,10,10,1,1,1\n"
    )
    r = _cli("track", seq, "--tracker", "meanshift", "--out", tmp_path / "o", "--no-plots")
    assert r.returncode == 0, r.stderr
    warns = [ln for ln in r.stderr.splitlines() if ln.startswith("dualtrack: warning:")]
    assert len(warns) == 1 and "1 duplicate (frame, id) rows, the first frame 2 id 1" in warns[0]


def test_a_truncated_png_is_one_line_that_says_what_libpng_said(tmp_path):
    from tests.conftest import write_boxes, write_frames

    seq = tmp_path / "s"
    write_frames(seq / "visible", 6, size=(160, 120), ext=".png")
    write_frames(seq / "infrared", 6, size=(160, 120), color=False, ext=".png")
    write_boxes(seq / "visible.txt", 6)
    bad = seq / "visible" / "00004.png"
    bad.write_bytes(bad.read_bytes()[: bad.stat().st_size // 2])
    r = _cli("track", seq, "--tracker", "meanshift", "--out", tmp_path / "o", "--no-plots")
    assert r.returncode == 1
    _only_line(r.stderr, "unreadable frame 4", str(bad), "(libpng error: ", "first 3 frames")


def test_a_file_named_mp4_that_is_no_video_is_one_line_that_says_what_ffmpeg_said(tmp_path):
    seq = tmp_path / "v"
    seq.mkdir()
    for ch in ("visible", "infrared"):
        (seq / f"{ch}.mp4").write_bytes(bytes(range(256)) * 20)
    r = _cli("track", seq, "--out", tmp_path / "o")
    assert r.returncode == 1
    _only_line(r.stderr, f"cannot open video {seq / 'visible.mp4'}", "FFmpeg: ")


def test_a_jpeg_that_decodes_with_a_complaint_gives_one_warning_at_the_end(tmp_path):
    seq = _tiny(tmp_path / "s", 5)
    f = sorted((seq / "visible").iterdir())[2]
    data = f.read_bytes()
    f.write_bytes(data[: len(data) * 2 // 3] + b"\xff\xd9")
    r = _cli("track", seq, "--tracker", "meanshift", "--out", tmp_path / "o", "--no-plots")
    assert r.returncode == 0, r.stderr
    assert r.stderr.splitlines() == [
        "dualtrack: warning: 1 message from the image/video libraries, the first: Corrupt JPEG "
        "data: premature end of data segment"
    ]


def test_a_newline_in_a_path_stays_on_one_line(tmp_path):
    seq = tmp_path / "a\nb"
    r = _cli("track", seq, "--out", tmp_path / "o")
    assert r.returncode == 1
    _only_line(r.stderr, "a\\nb")


@pytest.mark.parametrize("kind", ["dangling", "folder", "fifo"])
def test_an_entry_named_like_a_frame_that_is_no_file_is_named(tmp_path, kind):
    import os

    seq = _tiny(tmp_path / "s", 5)
    odd = seq / "infrared" / "00003b.jpg"  # sorts between frames 3 and 4
    if kind == "dangling":
        odd.symlink_to(tmp_path / "gone.jpg")
    elif kind == "folder":
        odd.mkdir()
    else:
        os.mkfifo(odd)
    r = _cli("track", seq, "--out", tmp_path / "o")
    assert r.returncode == 1
    what = {"dangling": "a broken symbolic link", "folder": "a folder", "fifo": "a FIFO"}[kind]
    _only_line(r.stderr, f"frame 4: {odd} is {what}")


def test_batch_with_a_failed_sequence_says_so_on_stderr(tmp_path):
    root = tmp_path / "root"
    _tiny(root / "good", 4)
    bad = _tiny(root / "bad", 4)
    (bad / "visible" / "00002.jpg").write_bytes(b"")
    r = _cli("batch", root, "--out", tmp_path / "out", "--trackers", "meanshift", "--no-plots")
    assert r.returncode == 1
    _only_line(r.stderr, "1 of 2 sequences failed", "bad", "00002.jpg", "report.md")


def test_a_run_folder_removed_mid_run_is_said_so(tmp_path, long_scene):
    import shutil

    run = tmp_path / "run"
    p = _start("track", long_scene, "--tracker", "mil", "--out", run)
    _wait_frames(run, 16, p)
    shutil.rmtree(run)
    _out, err = p.communicate(timeout=120)
    assert p.returncode == 1
    _only_line(err, f"the run folder {run} was removed during the run")
