"""RowFile: whole rows at checkpoints, a failed write undone."""

from __future__ import annotations

import pytest

from pipeline.errors import OutputError
from pipeline.sinks import rowfile
from pipeline.sinks.rowfile import RowFile


def test_rows_reach_the_file_only_at_checkpoints(tmp_path):
    f = RowFile(tmp_path / "a.csv", header="frame,x")
    f.add("1,2.5")
    assert (tmp_path / "a.csv").read_text() == "frame,x\n"
    f.checkpoint()
    f.close()
    assert (tmp_path / "a.csv").read_text() == "frame,x\n1,2.5\n"


@pytest.mark.parametrize("short", [0, 3])
def test_a_write_of_nothing_is_a_full_disk_not_a_retry(tmp_path, monkeypatch, short):
    """A write that writes nothing (after a short one, or at once) ends the checkpoint with
    OutputError instead of looping forever; the file is truncated back to its last checkpoint."""
    f = RowFile(tmp_path / "a.csv", header="frame,x")
    real = rowfile.os.write
    calls = []

    def write(fd, data):
        calls.append(len(data))
        if len(calls) > 3:  # a retry loop: fail here rather than hang the suite
            raise RuntimeError(f"write retried {len(calls)} times")
        if len(calls) == 1 and short:
            return real(fd, bytes(data[:short]))
        return 0

    monkeypatch.setattr(rowfile.os, "write", write)
    f.add("1,2.5")
    with pytest.raises(OutputError, match="No space left"):
        f.checkpoint()
    assert len(calls) <= 2
    monkeypatch.setattr(rowfile.os, "write", real)
    f.close()
    assert (tmp_path / "a.csv").read_text() == "frame,x\n"
