"""A full disk: every writing command stops with one line, status 2, and writes nothing at all.

Two ways for each command. In the test's own process the disk "fills" as the command's last output
is written (the writer gets ENOSPC after every other output was staged): the worst moment, since
everything before it must be taken back. And, as root where bubblewrap can mount a small private
tmpfs (``bwrap --size``), the real thing: ``out/`` is a tmpfs filled to the brim but for a few
pages, and the command runs in it; what is left in it is listed from inside the sandbox.
"""

from __future__ import annotations

import errno
import shutil
import subprocess
from pathlib import Path

import pytest
from command_outputs import COMMANDS, command, environment, error_lines, hidden, snapshot, workspace

from fidlearn import _staged, cli
from fidlearn import io as fidlearn_io

HEAVY = {"survey", "calibrate", "plan"}  # more than a few seconds each
NAMES = [pytest.param(name, marks=pytest.mark.slow) if name in HEAVY else name for name in COMMANDS]


def _full_at_last_output(monkeypatch, name: str) -> None:
    """The disk is full when the command writes its last output (every earlier one staged)."""
    n, real = len(COMMANDS[name][1]), _staged.file_mode_for
    calls = []

    def mode_then_full(path):
        calls.append(path)
        if len(calls) == n:  # called as each staged file is complete: this one did not fit
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(path)

    monkeypatch.setattr(_staged, "file_mode_for", mode_then_full)  # the staged outputs'
    monkeypatch.setattr(fidlearn_io, "file_mode_for", mode_then_full)  # the command's streamed ones (--json)


@pytest.mark.parametrize("name", NAMES)
def test_a_full_disk_writes_nothing(tmp_path, capsys, monkeypatch, name):
    ws = workspace(tmp_path)
    monkeypatch.chdir(ws)
    inputs = {k: v for k, v in snapshot(ws).items() if not k.startswith("out/")}
    _full_at_last_output(monkeypatch, name)
    status = cli.main(COMMANDS[name][0])
    out, err = capsys.readouterr()
    [line] = error_lines(err)
    assert status == 2, err
    assert err.rstrip().endswith(line), err
    assert "(No space left on device)" in line, line
    assert line.endswith("; nothing was written"), line
    assert "/." not in line  # the user's file named, never the hidden one
    assert snapshot(ws / "out") == {}
    assert not hidden(ws)
    assert {k: v for k, v in snapshot(ws).items() if not k.startswith("out/")} == inputs


def _bwrap_size_works(folder: Path) -> bool:
    if shutil.which("bwrap") is None:
        return False
    probe = ["bwrap", "--dev-bind", "/", "/", "--size", "65536", "--tmpfs", str(folder), "true"]
    return subprocess.run(probe, capture_output=True, timeout=60).returncode == 0


#: Bytes left free on the tiny disk: none where the outputs are smaller than a page.
FREE = {"corners": 0, "camera export": 0, "camera import": 0, "locate": 0}


@pytest.mark.parametrize("name", NAMES)
def test_a_really_full_disk_writes_nothing(tmp_path, name):
    ws = workspace(tmp_path)
    if not _bwrap_size_works(ws / "out"):
        pytest.skip("needs bubblewrap with --size (0.8.0) and the right to mount a tmpfs (root)")
    free = FREE.get(name, 16384)
    script = (
        "head -c 4000000 /dev/zero > out/.filler 2>/dev/null; "
        f"truncate -s -{free} out/.filler; "
        '"$@" 2> err.txt; echo $? > status.txt; '
        "rm out/.filler; find out -mindepth 1 > left.txt"
    )
    sandbox = ["bwrap", "--dev-bind", "/", "/", "--size", str(1 << 20), "--tmpfs", str(ws / "out")]
    done = subprocess.run(
        [*sandbox, "--chdir", str(ws), "sh", "-c", script, "sh", *command(COMMANDS[name][0])],
        env=environment(),
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    err = (ws / "err.txt").read_text()
    [line] = error_lines(err)
    assert (ws / "status.txt").read_text().strip() == "2", err
    assert err.rstrip().endswith(line), err
    assert "(No space left on device)" in line, line
    assert line.endswith("; nothing was written"), line
    assert (ws / "left.txt").read_text() == ""  # no output, no temporary file, in the sandbox's tmpfs
