"""``dualtrack bench``: one table with accuracy, tracker and end-to-end speed, decode rate."""

import json

from pipeline.bench import format_table, run_bench


def test_bench_table_and_json(scene, tmp_path):
    seq = scene("pole-fast")
    rows = run_bench([seq], ["meanshift", "camshift"], json_path=tmp_path / "b.json")
    assert [r["tracker"] for r in rows] == ["meanshift", "camshift"]
    for r in rows:
        assert r["frames"] == 32 and r["fps_decode"] > 0 and r["fps_tracking"] > 0 and r["fps_end_to_end"] > 0
        assert 0 <= r["p20"] <= 1 and 0 <= r["auc"] <= 1 and r["end_to_end_vs_decode"] > 0
    assert "camshift" in rows[0]["speed_vs_peers"]
    table = format_table(rows)
    assert "| sequence | tracker | P@20 | AUC | fps_tracking | fps_end_to_end | fps_decode | e2e/decode |" in table
    assert json.loads((tmp_path / "b.json").read_text())["rows"][1]["tracker"] == "camshift"
