"""``dualtrack bench``: one table with accuracy, tracker and end-to-end speed, decode rate."""

import json

import pytest

from pipeline.bench import format_table, run_bench


def test_bench_table_and_json(scene, tmp_path):
    seq = scene("pole-fast")
    rows = run_bench([seq], ["meanshift", "camshift"], json_path=tmp_path / "b.json")
    assert [r["tracker"] for r in rows] == ["meanshift", "camshift"]
    for r in rows:
        assert (
            r["frames"] == 32
            and r["fps_decode"] > 0
            and r["fps_tracking"] > 0
            and r["fps_end_to_end"] > 0
        )
        assert r["fps_tracking_cpu"] > 0
        assert 0 <= r["p20"] <= 1 and 0 <= r["auc"] <= 1 and r["end_to_end_vs_decode"] > 0
        ratio = r["fps_end_to_end"] / r["fps_decode_opencv"]
        assert r["end_to_end_vs_opencv_decode"] == pytest.approx(ratio, rel=1e-2, abs=1e-3)
    assert "camshift" in rows[0]["speed_vs_peers"] and "camshift" in rows[0]["speed_vs_peers_cpu"]
    cpu = [r["fps_tracking_cpu"] for r in rows]
    assert rows[0]["speed_vs_peers_cpu"]["camshift"] == round(cpu[0] / cpu[1], 2)
    table = format_table(rows)
    head = table.splitlines()[0]
    assert head == (
        "| sequence | tracker | P@20 | AUC | tracking fps | tracking fps (CPU) | end-to-end fps "
        "| decode fps |"
    )
    assert table.count("|---") == 8  # eight columns, each named in words
    assert "tracking fps: frames per second of wall time inside the tracker" in table
    assert json.loads((tmp_path / "b.json").read_text())["rows"][1]["tracker"] == "camshift"


def test_bench_repeat_keeps_the_fastest_run(scene, tmp_path, capsys):
    rows = run_bench([scene("pole-fast")], ["meanshift"], repeat=3)
    r = rows[0]
    assert r["repeat"] == 3 and len(r["fps_tracking_runs"]) == 3
    assert r["fps_tracking"] == max(r["fps_tracking_runs"]) and r["p20"] is not None
    from pipeline.cli import main

    assert main(["bench", str(scene("pole-fast")), "--repeat", "0"]) == 1
    err = capsys.readouterr().err
    assert "--repeat must be an integer >= 1" in err and err.count("\n") == 1


def test_bench_repeat_reports_the_kept_runs_ratio_and_stages(scene, monkeypatch):
    import types

    import pipeline.bench as B

    runs = iter(
        [(100.0, 50.0, 0.3), (300.0, 120.0, 0.1), (200.0, 150.0, 0.2)]
    )  # fps, e2e, stage seconds

    def fake_run(seq, opts):
        fps, e2e, sec = next(runs)
        return types.SimpleNamespace(
            summary={
                "fps_tracking": fps,
                "fps_end_to_end": e2e,
                "complete": True,
                "metrics": {"p20": 1.0, "auc": 0.8},
                "stage_seconds": {"x": sec},
            },
            error=None,
            interrupted=False,
        )

    monkeypatch.setattr(B, "run_track", fake_run)
    monkeypatch.setattr(B, "decode_rate", lambda *a, **k: (600.0, 32))
    r = B.run_bench([scene("pole-fast")], ["meanshift"], repeat=3)[0]
    assert r["fps_tracking"] == 300.0 and r["fps_end_to_end"] == 150.0  # each rate its best run
    assert r["end_to_end_vs_decode"] == 0.25  # of the printed end-to-end rate, not the last run's
    assert r["stage_seconds"] == {"x": 0.1}  # the stages of the fastest tracking run


def test_bench_runs_the_trackers_in_rounds(scene, monkeypatch):
    """Every tracker once, then every tracker again: a slow spell of the machine cannot fall on
    all of one tracker's runs and none of another's."""
    import types

    import pipeline.bench as B

    order: list[str] = []

    def fake_run(seq, opts):
        order.append(opts.tracker)
        fps = 100.0 + len(order)
        return types.SimpleNamespace(
            summary={"fps_tracking": fps, "fps_tracking_cpu": fps, "metrics": {"p20": 1.0}},
            error="broken" if opts.tracker == "camshift" and len(order) > 2 else None,
            interrupted=False,
        )

    monkeypatch.setattr(B, "run_track", fake_run)
    monkeypatch.setattr(B, "decode_rate", lambda *a, **k: (600.0, 32))
    rows = B.run_bench([scene("pole-fast")], ["meanshift", "camshift"], repeat=3)
    # camshift fails in the second round and is not run again; meanshift keeps its three
    assert order == ["meanshift", "camshift", "meanshift", "camshift", "meanshift"]
    assert rows[0]["fps_tracking_runs"] == [101.0, 103.0, 105.0]
    assert rows[0]["fps_tracking_cpu"] == 105.0
    assert rows[1]["failed"] == "broken" and "fps_tracking" not in rows[1]


def test_fps_vs_targets_table(tmp_path):
    from pipeline.bench import format_scaling, run_scaling

    rows = run_scaling([1, 2], ["meanshift"], out=tmp_path)
    assert [(r["tracker"], r["targets"]) for r in rows] == [("meanshift", 1), ("meanshift", 2)]
    assert rows[0]["per_target_cost_vs_first"] == 1.0 and rows[1]["per_target_cost_vs_first"] > 0
    assert rows[1]["ms_per_target"] == round(1000 / (rows[1]["fps_tracking"] * 2), 3)
    # two people in separate lanes: both followed, no identity confusion
    assert rows[1]["p20"] >= 0.95 and rows[1]["purity"] >= 0.95 and rows[1]["id_switches"] == 0
    # both always visible: the visible-frame figures are the all-frames ones
    assert (rows[1]["purity_visible"], rows[1]["idf1_visible"]) == (
        rows[1]["purity"],
        rows[1]["idf1"],
    )
    assert "| meanshift | 2 |" in format_scaling(rows)


def test_bench_targets_rejects_unknown_counts(capsys):
    from pipeline.cli import main

    assert main(["bench", "--targets", "3"]) == 1
    err = capsys.readouterr().err
    assert "no scene with 3 targets" in err and "\n" == err[-1] and err.count("\n") == 1
    assert main(["bench"]) == 1
    assert "needs sequence folders" in capsys.readouterr().err


def test_bench_random_prints_the_distribution_and_attributes(tmp_path, capsys):
    from pipeline.bench import format_distribution, run_random_bench

    res = run_random_bench(
        seeds=range(1, 3), trackers=["meanshift"], out=tmp_path, json_path=tmp_path / "r.json"
    )
    d = res["distribution"]["meanshift"]
    p20 = [r["p20"] for r in res["rows"]]
    assert d["scenes"] == 2 and res["seeds"] == [1, 2]
    assert abs(d["p20"]["mean"] - sum(p20) / 2) < 1e-12 and d["p20"]["worst"] == min(p20)
    assert d["p20"]["worst_seed"] == res["rows"][p20.index(min(p20))]["seed"]
    assert res["attributes"]["meanshift"], "per-attribute scores from the scenes' frame flags"
    text = format_distribution(res)
    assert "| meanshift | 2 |" in text and "P@20 / AUC over the frames with each attribute" in text
    assert json.loads((tmp_path / "r.json").read_text())["seeds"] == [1, 2]
    # a second run reuses the generated scenes
    before = (tmp_path / "scenes" / "random-0001" / "visible" / "00001v.jpg").stat().st_mtime_ns
    run_random_bench(seeds=range(1, 2), trackers=["meanshift"], out=tmp_path)
    assert (
        tmp_path / "scenes" / "random-0001" / "visible" / "00001v.jpg"
    ).stat().st_mtime_ns == before


def test_bench_random_runs_one_channel_when_asked(tmp_path, capsys):
    """``bench --random/--seeds --channel visible`` runs the trackers on the scenes' visible
    frames alone (it ran both channels, silently, before); ``--channel`` with ``--targets`` is
    refused."""
    from pipeline.cli import main

    args = ["bench", "--seeds", "1", "--random-targets", "1", "--trackers", "meanshift"]
    for channel in ("visible", "infrared"):
        out = tmp_path / channel
        assert main([*args, "--channel", channel, "--out", str(out)]) == 0
        summary = json.loads(
            (out / "runs" / "meanshift" / "random-0001-t1-1" / "summary.json").read_text()
        )
        assert summary["channels"] == [channel]
    assert main([*args, "--out", str(tmp_path / "both")]) == 0
    summary = json.loads(
        (
            tmp_path / "both" / "runs" / "meanshift" / "random-0001-t1-1" / "summary.json"
        ).read_text()
    )
    assert sorted(summary["channels"]) == ["infrared", "visible"]
    capsys.readouterr()
    assert main(["bench", "--targets", "1", "--channel", "visible"]) == 1
    assert "--channel applies to sequence folders" in capsys.readouterr().err


def test_bench_random_rejects_bad_options(capsys):
    from pipeline.cli import main

    assert main(["bench", "--random", "0"]) == 1
    assert "--random takes a number of scenes >= 1" in capsys.readouterr().err
    assert main(["bench", "--seeds", "4-2"]) == 1
    assert "seeds must be N or A-B" in capsys.readouterr().err


def test_the_cpu_rate_counts_only_the_trackers_own_work(scene, monkeypatch, tmp_path):
    """A tracker that waits (a sleep: wall time, no CPU) 20 ms on every frame after the first
    (the first frame starts the engine, it is not a step): its tracking rate is at most
    50 frames/s times frames / steps, its rate in CPU time far higher; the waiting is what the
    reader and writer threads cost a tracker beside them."""
    import time

    from pipeline.run import RunOptions, run_track
    from pipeline.trackers import base

    opts = RunOptions(
        tracker="meanshift",
        out_dir=tmp_path / "r",
        rrd=False,
        plots=False,
        progress=False,
        force=True,
    )
    run_track(scene("pole-fast"), opts)  # compiles the kernels (a fresh clone has no cache)
    slow_step = base.CoreEngine.step

    def waiting(self, frames):
        time.sleep(0.02)
        return slow_step(self, frames)

    monkeypatch.setattr(base.CoreEngine, "step", waiting)
    s = run_track(scene("pole-fast"), opts).summary
    n = s["frames"]
    assert s["fps_tracking"] <= 50 * n / (n - 1) and s["fps_tracking_cpu"] > 3 * s["fps_tracking"]


def test_random_scene_set_reuses_a_scene_written_by_synth_random(tmp_path):
    """A ``dualtrack synth random`` folder (``random-NNNN``) with the same generator options is
    reused, not written again beside it as ``random-NNNN-tA-B``; with other options the scene is
    written under its own name."""
    from pipeline.bench import random_scene_set
    from pipeline.synthetic import synthesize_random

    out = tmp_path / "scenes"
    synthesize_random(out / "random-0003", 3, (2, 3), (160, 120), 30, progress=False)
    opts = {"seeds": range(3, 4), "targets": (2, 3), "out": out, "size": (160, 120)}
    same = random_scene_set(**opts, frames=30)
    assert same == [out / "random-0003"]
    assert sorted(p.name for p in out.iterdir()) == ["random-0003"]
    other = random_scene_set(**opts, frames=31)
    assert other == [out / "random-0003-t2-3"]
    assert (out / "random-0003-t2-3" / "scene.json").is_file()
