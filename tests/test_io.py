"""fidlearn._io: atomic writes leave files with the permissions a plain write would give."""

from __future__ import annotations

import os
import stat

import pytest

from fidlearn._io import atomic_write, write_json_atomic

pytestmark = pytest.mark.skipif(os.name != "posix", reason="POSIX permission bits")


def mode(path) -> int:
    return stat.S_IMODE(os.stat(path).st_mode)


def test_new_file_gets_umask_permissions_not_mkstemp_private(tmp_path):
    # mkstemp creates 0o600 files; renamed as they were, every camera.json, PDF and annotated
    # image was unreadable to other users (umask 022 should give 0o644).
    old = os.umask(0o022)
    try:
        out = write_json_atomic(tmp_path / "camera.json", {"a": 1})
        assert mode(out) == 0o644
        os.umask(0o077)
        private = write_json_atomic(tmp_path / "private.json", {"a": 1})
        assert mode(private) == 0o600
    finally:
        os.umask(old)


def test_existing_file_keeps_its_permissions(tmp_path):
    path = tmp_path / "poses.jsonl"
    path.write_text("old\n")
    os.chmod(path, 0o640)
    atomic_write(path, lambda tmp: tmp.write_text("new\n"))
    assert path.read_text() == "new\n"
    assert mode(path) == 0o640
