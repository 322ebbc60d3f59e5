"""Where files can be made (swiptopt.files): the check the CLI, the store and a models
directory share."""

from __future__ import annotations

import os

from swiptopt.files import can_make_files_in, existing_ancestor


def test_the_nearest_existing_ancestor_is_where_missing_directories_would_be_made(tmp_path):
    assert existing_ancestor(tmp_path / "a" / "b" / "c") == tmp_path
    assert existing_ancestor(tmp_path) == tmp_path
    (tmp_path / "f").write_text("x", encoding="utf-8")
    assert existing_ancestor(tmp_path / "f" / "g") == tmp_path / "f"


def test_files_can_be_made_below_a_writable_directory_not_below_a_file_or_a_read_only_one(tmp_path, monkeypatch):
    assert can_make_files_in(tmp_path) and can_make_files_in(tmp_path / "new" / "deeper")
    (tmp_path / "f").write_text("x", encoding="utf-8")
    assert not can_make_files_in(tmp_path / "f") and not can_make_files_in(tmp_path / "f" / "g")
    locked = tmp_path / "locked"
    locked.mkdir()
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode, **kw: False if str(p) == str(locked) else real(p, mode, **kw))
    assert not can_make_files_in(locked) and not can_make_files_in(locked / "missing")
    assert can_make_files_in(tmp_path / "other")
