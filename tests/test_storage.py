"""Atomic writes: whole files or none, and files written together change together."""

from __future__ import annotations

import pytest

from prehensile.storage import atomic_write_files, atomic_write_json, json_bytes


def test_files_written_together_change_together(tmp_path):
    first, second = tmp_path / "a.json", tmp_path / "sub" / "b.bin"
    assert atomic_write_files({first: json_bytes({"run": 1}), second: b"one"}) == [first, second]
    assert first.read_bytes() == b'{\n  "run": 1\n}\n' and second.read_bytes() == b"one"
    (tmp_path / "blocked").write_text("a file where a folder is needed")
    with pytest.raises(OSError):  # the third file cannot be staged: neither of the others changes
        atomic_write_files({first: b"two", second: b"two", tmp_path / "blocked" / "c": b"two"})
    assert first.read_bytes() == b'{\n  "run": 1\n}\n' and second.read_bytes() == b"one"
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["a.json", "b.bin", "blocked", "sub"]  # no temp files


def test_a_written_file_is_readable_by_others(tmp_path):
    path = atomic_write_json(tmp_path / "report.json", [1, 2])
    assert path.read_text() == "[\n  1,\n  2\n]\n" and path.stat().st_mode & 0o777 == 0o644
