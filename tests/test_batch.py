"""``dualtrack batch``: discovery, local pool, fault isolation, resume, report, export, Dask on
loopback."""

from __future__ import annotations

import json
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from pipeline.batch import BatchOptions, discover, run_batch
from pipeline.errors import InputError


def tiny_pair(folder: Path, n: int = 16, dx: int = 1, seed: int = 0) -> Path:
    """An RGBT234-layout pair: a warm red square moving right on noise, with its truth."""
    rng = np.random.default_rng(seed)
    (folder / "visible").mkdir(parents=True)
    (folder / "infrared").mkdir()
    rows = []
    for i in range(n):
        x = 12 + dx * i
        v = rng.integers(60, 90, (60, 80, 3), dtype=np.uint8)
        v[20:36, x : x + 12] = (40, 40, 210)
        ir = rng.integers(40, 60, (60, 80), dtype=np.uint8)
        ir[20:36, x : x + 12] = 200
        cv2.imwrite(str(folder / "visible" / f"{i + 1:05d}v.jpg"), v)
        cv2.imwrite(str(folder / "infrared" / f"{i + 1:05d}i.jpg"), ir)
        rows.append(f"{x},20,12,16")
    for f in ("visible.txt", "infrared.txt"):
        (folder / f).write_text("\n".join(rows) + "\n")
    return folder


@pytest.fixture
def archive(tmp_path: Path) -> Path:
    root = tmp_path / "archive"
    tiny_pair(root / "a", seed=1)
    tiny_pair(root / "b", dx=2, seed=2)
    tiny_pair(root / "group" / "c", seed=3)
    (root / "notes").mkdir()
    (root / "notes" / "readme.txt").write_text("no frames here\n")
    return root


def test_discover_finds_nested_sequences_and_skips_folders_without_frames(archive, tmp_path):
    found = discover(archive)
    assert [n for n, _ in found] == ["a", "b", "group/c"]
    assert discover(archive / "a") == [("a", archive / "a")]  # the root itself is a sequence
    out = archive / "runs"
    tiny_pair(out / "old", seed=9)  # a previous batch's folder under ROOT is not an input
    assert [n for n, _ in discover(archive, exclude=out)] == ["a", "b", "group/c"]
    with pytest.raises(InputError, match="not found"):
        discover(tmp_path / "missing")


def test_local_batch_isolates_a_corrupt_sequence_resumes_and_reports(archive, tmp_path):
    bad = archive / "b" / "infrared" / "00008i.jpg"
    bad.write_bytes(bad.read_bytes()[:100])
    out = tmp_path / "out"
    opts = BatchOptions(
        trackers=("dual", "meanshift"), workers=2, export="rgbt234", progress=False
    )
    res = run_batch(archive, out, opts)
    status = {r.task.key: r.status for r in res.results}
    assert status == {
        "dual/a": "done",
        "meanshift/a": "done",
        "dual/b": "failed",
        "meanshift/b": "failed",
        "dual/group/c": "done",
        "meanshift/group/c": "done",
    }
    report = json.loads((out / "report.json").read_text())
    failed = report["sequences"]["dual/b"]
    assert (
        failed["status"] == "failed"
        and "00008i.jpg" in failed["error"]
        and "frame 8" in failed["error"]
    )
    done = report["sequences"]["dual/a"]
    assert (
        done["metrics"]["p20"] == 1.0 and done["fps_tracking"] > 0 and done["run_dir"] == "dual/a"
    )
    ov = report["overall"]["dual"]
    assert (
        (ov["done"], ov["failed"], ov["skipped"]) == (2, 1, 0)
        and ov["sequences"] == 2
        and ov["p20"] == pytest.approx(1.0)
    )
    assert len(ov["precision_curve"]) == 51 and len(ov["success_curve"]) == 21
    assert (out / "report.md").read_text().count("| dual |") == 1
    assert (out / "plots" / "precision.png").is_file() and (
        out / "plots" / "success.png"
    ).is_file()
    lines = (out / "export" / "rgbt234" / "dual" / "dual_a.txt").read_text().splitlines()
    assert len(lines) == 16 and lines[0].startswith(
        "12.0,20.0,"
    )  # full precision, the first frame's box
    # the finished sequences stay as they were; a re-run skips them and retries the failure
    before = (out / "dual" / "a" / "tracks.csv").stat().st_mtime_ns
    again = run_batch(archive, out, opts)
    status = {r.task.key: r.status for r in again.results}
    assert (
        status["dual/a"] == "skipped"
        and status["meanshift/group/c"] == "skipped"
        and status["dual/b"] == "failed"
    )
    assert (out / "dual" / "a" / "tracks.csv").stat().st_mtime_ns == before
    assert json.loads((out / "report.json").read_text())["overall"]["dual"][
        "p20"
    ] == pytest.approx(1.0)


def test_gtot_protocol_pools_frames(archive, tmp_path):
    out = tmp_path / "out"
    res = run_batch(
        archive,
        out,
        BatchOptions(trackers=("meanshift",), workers=2, protocol="gtot", progress=False),
    )
    assert all(r.status == "done" for r in res.results)
    ov = json.loads((out / "report.json").read_text())["overall"]["meanshift"]
    assert ov["pooled_frames"] == 48 and 0 <= ov["mpr"] <= 1 and "p20" not in ov


def test_batch_cli_errors_are_one_line(tmp_path, capsys):
    from pipeline.cli import main

    assert main(["batch", str(tmp_path / "nope"), "--out", str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("dualtrack: error: archive root not found") and err.count("\n") == 1
    (tmp_path / "empty").mkdir()
    assert main(["batch", str(tmp_path / "empty"), "--out", str(tmp_path / "o")]) == 1
    assert "no sequence folders" in capsys.readouterr().err
    tiny_pair(tmp_path / "one")
    assert (
        main(
            ["batch", str(tmp_path / "one"), "--out", str(tmp_path / "o"), "--trackers", "nosuch"]
        )
        == 1
    )
    assert "unknown tracker 'nosuch'" in capsys.readouterr().err


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def dask_cluster(tmp_path):
    """A real ``dask scheduler`` and two ``dask worker`` processes on loopback."""
    pytest.importorskip("distributed")
    dask = str(
        Path(sys.executable).with_name("dask")
    )  # the environment running the tests, not PATH's
    if not Path(dask).exists():
        dask = shutil.which("dask") or dask
    if not Path(dask).exists():
        pytest.skip("the dask command is not installed (pip install -e '.[cluster]')")
    port = _free_port()
    addr = f"tcp://127.0.0.1:{port}"
    logs = [open(tmp_path / f"dask{i}.log", "w") for i in range(3)]
    procs = [
        subprocess.Popen(
            [dask, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
            stdout=logs[0],
            stderr=subprocess.STDOUT,
        )
    ]
    try:
        from distributed import Client

        for i in (1, 2):
            procs.append(
                subprocess.Popen(
                    [
                        dask,
                        "worker",
                        addr,
                        "--nthreads",
                        "1",
                        "--no-dashboard",
                        "--name",
                        f"w{i}",
                        "--local-directory",
                        str(tmp_path / f"w{i}"),
                    ],
                    stdout=logs[i],
                    stderr=subprocess.STDOUT,
                )
            )
        deadline = time.time() + 60
        while True:
            try:
                with Client(addr, timeout="5s") as c:
                    c.wait_for_workers(2, timeout=max(deadline - time.time(), 1))
                break
            except (OSError, TimeoutError):
                if time.time() > deadline:
                    raise
                time.sleep(0.5)
        yield addr
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
        for f in logs:
            f.close()


def test_dask_cluster_results_equal_a_local_run(archive, tmp_path, dask_cluster):
    local = run_batch(
        archive, tmp_path / "local", BatchOptions(trackers=("dual",), workers=2, progress=False)
    )
    assert all(r.status == "done" for r in local.results)
    for ship in (False, True):
        out = tmp_path / f"dask-{ship}"
        res = run_batch(
            archive,
            out,
            BatchOptions(
                trackers=("dual",), scheduler=dask_cluster, ship_frames=ship, progress=False
            ),
        )
        assert [r.status for r in res.results] == ["done", "done", "done"], [
            r.error for r in res.results
        ]
        for name in ("a", "b", "group/c"):
            assert (out / name / "tracks.csv").read_text() == (
                tmp_path / "local" / name / "tracks.csv"
            ).read_text()
            assert (out / name / "run.rrd").stat().st_size > 0
        rep = json.loads((out / "report.json").read_text())
        assert (
            rep["overall"]["dual"]["p20"]
            == json.loads((tmp_path / "local" / "report.json").read_text())["overall"]["dual"][
                "p20"
            ]
        )


def test_batch_passes_track_s_reading_options_to_every_run(tmp_path):
    """``batch --channel --gt-base --frames --no-plots`` reach each run's ``track`` command."""
    from pipeline.batch import BatchOptions, track_command

    opts = BatchOptions(channel="infrared", gt_base=1.0, stop_frame=40, plots=False)
    cmd = track_command(tmp_path / "seq", "dual", tmp_path / "run", opts)
    text = " ".join(cmd)
    for part in ("--channel infrared", "--gt-base 1", "--frames 40", "--no-plots"):
        assert part in text, part
    plain = " ".join(track_command(tmp_path / "seq", "dual", tmp_path / "run", BatchOptions()))
    assert "--channel" not in plain and "--frames" not in plain


def test_the_mot_export_is_the_layout_trackeval_reads_and_scores_as_we_do(tmp_path):
    """``--export mot``: ``gt/<seq>/gt/gt.txt`` with ``seqinfo.ini``, ``trackers/<tracker>/data/
    <seq>.txt`` and ``seqmap.txt``; the exported truth and results, read back, score as the run
    did (sparse truth: the annotated frames only, in both files)."""
    from pipeline.eval import evaluate
    from pipeline.io.groundtruth import parse_mot_truth
    from pipeline.io.results import read_tracks
    from pipeline.io.sequence import Truth

    root = tmp_path / "archive"
    tiny_pair(root / "a")
    vt = tiny_pair(root / "b", n=25)  # the VTUAV layout: truth on every 10th frame
    (vt / "visible").rename(vt / "rgb")
    (vt / "infrared").rename(vt / "ir")
    rows = (vt / "visible.txt").read_text().splitlines()
    for f in ("visible.txt", "infrared.txt"):
        (vt / f).unlink()
    for f in ("rgb.txt", "ir.txt"):
        (vt / f).write_text("".join(rows[k].replace(",", " ") + "\n" for k in (0, 10, 20)))
    res = run_batch(root, tmp_path / "out", BatchOptions(export="mot", progress=False))
    assert {r.status for r in res.results} == {"done"}
    base = tmp_path / "out" / "export" / "mot"
    assert (base / "seqmap.txt").read_text().split() == ["name", "a", "b"]
    for seq, n in (("a", 16), ("b", 25)):
        assert f"seqLength={n}" in (base / "gt" / seq / "seqinfo.ini").read_text()
        mt = parse_mot_truth(base / "gt" / seq / "gt" / "gt.txt", n)
        tracks = read_tracks(base / "trackers" / "dual" / "data" / f"{seq}.txt", n)
        every = 10 if seq == "b" else 1
        got = evaluate(Truth({"visible": mt.boxes}, multi=True, sparse_every=every), tracks, n)
        run = json.loads((tmp_path / "out" / seq / "summary.json").read_text())["metrics"]
        assert got["p20"] == pytest.approx(run["p20"]) and got["auc"] == pytest.approx(run["auc"])
    frames = {
        int(r.split(",")[0]) for r in (base / "trackers/dual/data/b.txt").read_text().split()
    }
    assert frames == {1, 11, 21}  # the annotated frames only, as its gt.txt
