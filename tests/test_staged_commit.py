"""A commit of staged outputs is all or none, even when a rename fails half-way through it.

:meth:`fidlearn.io.StagedOutputs.commit` renames its hidden files to their names one after the
other. Here a rename fails in the middle (``os.replace`` refuses one destination, as a full disk or
a folder made read-only would): every file the same commit renamed before it must hold what it held
before, byte for byte with its mode, a name that held nothing must hold nothing again, no hidden
file may be left behind, and the error must name the user's file and say that nothing was written.
"""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

import pytest

from fidlearn import _staged
from fidlearn.errors import FidlearnError
from fidlearn.io import StagedOutputs

NAMES = ["a.txt", "b.txt", "c.txt"]  # committed in this order
BEFORE = {"a.txt": (b"old a\n", 0o640), "c.txt": (b"old c\n", 0o604)}  # b.txt does not exist yet
FULL = OSError(errno.ENOSPC, "No space left on device")


@pytest.fixture(params=["hard links", "no hard links"], autouse=True)
def links(request, monkeypatch):
    """Run each case where the disk makes hard links and where it has none (the files are then renamed aside)."""
    if request.param == "no hard links":

        def no_link(*_args, **_kwargs):
            raise OSError(errno.EPERM, "Operation not permitted")

        monkeypatch.setattr(_staged.os, "link", no_link)
    return request.param


def _refuse_output(monkeypatch, path: Path) -> None:
    """Renaming a new output to ``path`` fails (putting back the file it held still works)."""
    _refuse(monkeypatch, lambda src, dst: dst == path and src.suffix != ".old")


def _refuse(monkeypatch, refused) -> None:
    """``os.replace`` fails (a full disk) where ``refused(src, dst)`` says so, and works elsewhere."""
    real = os.replace

    def replace(src, dst):
        if refused(Path(src), Path(dst)):
            raise FULL
        return real(src, dst)

    monkeypatch.setattr(_staged.os, "replace", replace)


def _files(folder: Path) -> dict[str, tuple[bytes, int]]:
    """Every file in ``folder`` (hidden ones too): name -> (bytes, permission bits)."""
    return {p.name: (p.read_bytes(), stat.S_IMODE(p.stat().st_mode)) for p in sorted(folder.iterdir())}


def _earlier_files(folder: Path) -> dict[str, tuple[bytes, int]]:
    for name, (data, mode) in BEFORE.items():
        (folder / name).write_bytes(data)
        os.chmod(folder / name, mode)
    return _files(folder)


def _stage(outputs: StagedOutputs, folder: Path, names=NAMES) -> None:
    for name in names:
        outputs.stage(folder / name, lambda tmp, name=name: tmp.write_bytes(f"new {name}\n".encode()))


@pytest.mark.parametrize("failing", ["b.txt", "c.txt"])
def test_a_failed_rename_puts_back_every_file_renamed_before_it(tmp_path, monkeypatch, failing):
    before = _earlier_files(tmp_path)
    _refuse_output(monkeypatch, tmp_path / failing)
    outputs = StagedOutputs()
    with pytest.raises(FidlearnError) as err, outputs:
        _stage(outputs, tmp_path)
    assert _files(tmp_path) == before  # a.txt's old bytes and mode, no b.txt, c.txt untouched, nothing hidden
    assert not os.path.lexists(tmp_path / "b.txt")
    message = str(err.value)
    assert message.startswith(f"{tmp_path / failing}: cannot write it (No space left on device); "), message
    assert message.endswith("; nothing was written"), message
    assert "/." not in message  # the user's file named, never a hidden one
    assert outputs.committed == []
    assert outputs.staged == []
    assert outputs.written() == "nothing was written"


def test_after_an_earlier_commit_the_error_says_nothing_more_was_written(tmp_path, monkeypatch):
    before = _earlier_files(tmp_path)
    _refuse_output(monkeypatch, tmp_path / "b.txt")
    with StagedOutputs() as outputs:
        _stage(outputs, tmp_path, ["first.txt"])
        assert outputs.commit() == [tmp_path / "first.txt"]
        _stage(outputs, tmp_path)
        with pytest.raises(FidlearnError) as err:
            outputs.commit()
    assert _files(tmp_path) == {**before, "first.txt": (b"new first.txt\n", _staged.file_mode_for(tmp_path / "x"))}
    assert str(err.value).endswith(f"; nothing more was written; written: {tmp_path / 'first.txt'}"), err.value
    assert [e.path for e in outputs.committed] == [tmp_path / "first.txt"]
    assert outputs.staged == []


def test_a_successful_commit_leaves_no_file_kept_aside(tmp_path):
    _earlier_files(tmp_path)
    with StagedOutputs() as outputs:
        _stage(outputs, tmp_path)
    new_mode = _staged.file_mode_for(tmp_path / "x")
    assert _files(tmp_path) == {
        "a.txt": (b"new a.txt\n", 0o640),  # an existing file keeps its mode
        "b.txt": (b"new b.txt\n", new_mode),
        "c.txt": (b"new c.txt\n", 0o604),
    }
    assert [e.path for e in outputs.committed] == [tmp_path / name for name in NAMES]
    assert outputs.staged == []


def test_a_commit_of_some_entries_renames_them_and_keeps_the_others_staged(tmp_path, monkeypatch):
    _earlier_files(tmp_path)
    with StagedOutputs() as outputs:
        entries = []
        for name in NAMES:
            entry = outputs.temp(tmp_path / name)
            entry.tmp.write_bytes(f"new {name}\n".encode())
            os.chmod(entry.tmp, _staged.file_mode_for(entry.path))  # as a stream of records does
            entry.whole = True
            entries.append(entry)
        assert outputs.commit([entries[0], entries[2]]) == [tmp_path / "a.txt", tmp_path / "c.txt"]
        assert outputs.staged == [entries[1]]
        assert sorted(p.name for p in tmp_path.iterdir()) == [entries[1].tmp.name, "a.txt", "c.txt"]
        _refuse_output(monkeypatch, tmp_path / "b.txt")
        with pytest.raises(FidlearnError) as err:
            outputs.commit()
    assert str(err.value).endswith(f"; nothing more was written; written: {tmp_path / 'a.txt'}, {tmp_path / 'c.txt'}")
    assert _files(tmp_path) == {"a.txt": (b"new a.txt\n", 0o640), "c.txt": (b"new c.txt\n", 0o604)}
    assert outputs.committed == [entries[0], entries[2]]


def test_a_symbolic_link_replaced_then_put_back_is_the_link_again(tmp_path, monkeypatch):
    (tmp_path / "target.txt").write_text("the target")
    (tmp_path / "a.txt").symlink_to("target.txt")
    (tmp_path / "c.txt").symlink_to("gone.txt")  # dangling
    _refuse_output(monkeypatch, tmp_path / "b.txt")
    with pytest.raises(FidlearnError), StagedOutputs() as outputs:
        _stage(outputs, tmp_path)
    assert os.readlink(tmp_path / "a.txt") == "target.txt"
    assert os.readlink(tmp_path / "c.txt") == "gone.txt"
    assert (tmp_path / "target.txt").read_text() == "the target"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "c.txt", "target.txt"]


def _stage_pictures_and_report(outputs: StagedOutputs, seen: Path, report: Path) -> None:
    staging = outputs.staging_folder(seen)  # as --annotate stages its pictures
    for name in ("p1.png", "p2.png"):
        outputs.stage(seen / name, lambda tmp: tmp.write_bytes(b"png"), folder=staging, group=seen)
    outputs.stage(report, lambda tmp: tmp.write_text("{}"))


def test_a_folder_of_pictures_made_by_a_failed_commit_is_removed(tmp_path, monkeypatch):
    seen = tmp_path / "seen"
    _refuse_output(monkeypatch, tmp_path / "report.json")
    with pytest.raises(FidlearnError) as err, StagedOutputs() as outputs:
        _stage_pictures_and_report(outputs, seen, tmp_path / "report.json")
    assert list(tmp_path.iterdir()) == []
    assert str(err.value).endswith("; nothing was written")


def test_a_file_that_cannot_be_put_back_is_said_to_be_written(tmp_path, monkeypatch):
    """If even the way back fails, the error says so and counts the file as written: never a false "nothing"."""
    _earlier_files(tmp_path)
    _refuse(monkeypatch, lambda src, dst: dst == tmp_path / "b.txt" or src.suffix == ".old")  # no way back
    outputs = StagedOutputs()
    with pytest.raises(FidlearnError) as err, outputs:
        _stage(outputs, tmp_path)
    message = str(err.value)
    assert f"{tmp_path / 'a.txt'} could not be put back as it was (No space left on device)" in message, message
    assert message.endswith(f"; written: {tmp_path / 'a.txt'}"), message
    assert "nothing" not in message
    assert [e.path for e in outputs.committed] == [tmp_path / "a.txt"]
    assert (tmp_path / "a.txt").read_bytes() == b"new a.txt\n"
    [kept] = [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # named in the message, nothing else left
    assert kept.read_bytes() == b"old a\n"
    assert str(kept) in message
