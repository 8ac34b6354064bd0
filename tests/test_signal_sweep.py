"""A signal at any moment of a command's life: every output written and whole, or none; the line says which.

Each writing command runs once to its end (its outputs are the reference and its duration its
life), then again and again with SIGTERM (SIGINT for ``calibrate``) sent at a sweep of times across
that life, past its end included. After each run: either every output exists, byte for byte the
reference's, or none does; no hidden temporary file anywhere; and the one ``error:`` line says
``nothing was written`` only when that is true, or names every output written. Timings cannot hit
the commit itself reliably, so the real commit is also interrupted at exact steps:
``FIDLEARN_TEST_SIGNAL_AT`` makes the process send itself the signal after its last output is
staged, after the first rename of the commit, and right after the commit.
"""

from __future__ import annotations

import math
import signal
import subprocess
import time
from collections import Counter
from pathlib import Path

import pytest
from command_outputs import (
    COMMANDS,
    command,
    environment,
    error_lines,
    hidden,
    run,
    same_outputs,
    snapshot,
    workspace,
)
from helpers import ctrl_c_as_a_terminal_gives_it

from fidlearn._io import SIGNAL_AT_VARIABLE


@pytest.fixture(autouse=True)
def _ctrl_c():
    with ctrl_c_as_a_terminal_gives_it():
        yield


SWEPT = ["survey", "calibrate", "render", "plan", "markers", "board", "corners"]


def reference(tmp_path: Path, name: str) -> tuple[Path, float]:
    """The folder of an uninterrupted run's outputs and the run's duration, s."""
    ws = workspace(_fresh(tmp_path / "reference"))
    t0 = time.perf_counter()
    done = run(ws, COMMANDS[name][0])
    life = time.perf_counter() - t0
    assert done.returncode == 0, done.stderr
    assert sorted(snapshot(ws / "out")) == sorted(COMMANDS[name][1])
    return ws / "out", life


def _fresh(folder: Path) -> Path:
    folder.mkdir(parents=True)
    return folder


def interrupted(ws: Path, argv: list[str], after_s: float, sig: int) -> tuple[int, str]:
    """Run ``fidlearn ARGV`` in ``ws``, send it ``sig`` after ``after_s`` seconds; its status and stderr."""
    proc = subprocess.Popen(
        command(argv), cwd=ws, env=environment(), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True
    )
    try:
        proc.wait(timeout=after_s)
    except subprocess.TimeoutExpired:
        proc.send_signal(sig)
    _, err = proc.communicate(timeout=600)
    return proc.returncode, err


def outcome(ws: Path, status: int, err: str, sig: int, ref: Path) -> str:
    """Check one run's outputs against its status and its error line; the kind of outcome."""
    got = snapshot(ws / "out")
    assert not hidden(ws), f"temporary files left behind: {hidden(ws)}"
    lines = error_lines(err)
    if status == 0:  # done before the signal (or while it exited, when a signal changes nothing)
        assert same_outputs(ws / "out", ref), err
        assert not lines, err
        return "finished"
    if status == -sig:  # before fidlearn's own code ran: Python was still importing numpy and OpenCV
        assert got == {}, err
        assert not lines, err
        return "killed while Python started"
    assert status == 128 + sig, err
    assert len(lines) == 1, err
    assert err.rstrip().endswith(lines[0]), err
    line = lines[0]
    assert line.startswith(f"error: interrupted by {signal.Signals(sig).name}; "), line
    if line.endswith("; nothing was written"):
        assert got == {}, (line, sorted(got))
        return "nothing written"
    assert same_outputs(ws / "out", ref), (line, sorted(got))  # every output, whole
    for name in snapshot(ref):
        folder, _, _ = name.rpartition("/")
        said = f"annotated pictures in out/{folder}/" if folder else f"out/{name}"
        assert said in line, line
    return "all written"


AT_WORK = ("nothing written", "all written")


def sweep(tmp_path: Path, name: str, fractions: list[float], sig: int, narrow: int = 0) -> Counter:
    """Interrupt ``name`` at each fraction of its life; the outcomes counted.

    A short command spends most of its life starting Python, and a loaded machine moves its short
    working window: when no signal of the sweep lands in it, up to ``narrow`` more are sent by
    bisection between the latest one that came while Python started and the earliest after the end.
    """
    ref, life = reference(tmp_path, name)
    seen: Counter = Counter()
    early, late = 0.0, math.inf
    for k, fraction in enumerate(fractions):
        ws = workspace(_fresh(tmp_path / f"at{k}"))
        status, err = interrupted(ws, COMMANDS[name][0], fraction * life, sig)
        result = outcome(ws, status, err, sig, ref)
        seen[result] += 1
        if result == "killed while Python started":
            early = max(early, fraction)
        elif result == "finished":
            late = min(late, fraction)
    for k in range(narrow):
        if any(seen[r] for r in AT_WORK) or math.isinf(late):
            break
        fraction = (early + late) / 2 if early < late else late * (0.9 + 0.05 * k)
        ws = workspace(_fresh(tmp_path / f"narrow{k}"))
        status, err = interrupted(ws, COMMANDS[name][0], fraction * life, sig)
        result = outcome(ws, status, err, sig, ref)
        seen[result] += 1
        if result == "killed while Python started":
            early = fraction
        elif result == "finished":
            late = fraction
    return seen


def at_step(tmp_path: Path, name: str, ref: Path, step: str) -> str:
    """Interrupt ``name`` at an exact step of its commit (``staged:N``, ``renamed:N``, ``committed:N``)."""
    ws = workspace(_fresh(tmp_path / step.replace(":", "_")))
    done = run(ws, COMMANDS[name][0], **{SIGNAL_AT_VARIABLE: f"{step}:SIGTERM"})
    assert done.returncode == 128 + signal.SIGTERM, done.stderr
    return outcome(ws, done.returncode, done.stderr, signal.SIGTERM, ref)


def steps(name: str) -> dict[str, str]:
    """The commit's steps and what a signal there must leave."""
    n = len(COMMANDS[name][1])
    return {
        f"staged:{n}": "nothing written",  # the last output staged, none renamed yet
        "renamed:1": "all written",  # the renames are not interrupted half-way
        "committed:1": "all written",
    }


@pytest.mark.slow
@pytest.mark.parametrize("name", SWEPT)
def test_a_signal_at_any_time_leaves_all_outputs_or_none(tmp_path, name):
    sig = signal.SIGINT if name == "calibrate" else signal.SIGTERM
    # 0.25 .. 1.03 of the measured life, and past it (a loaded machine stretches a run's life); the
    # bisection of sweep() adds times when none lands at work, and the exact end, when the outputs
    # appear, is hit by the steps below
    fractions = [0.25 + 0.13 * k for k in range(7)] + [1.5]
    seen = sweep(tmp_path, name, fractions, sig, narrow=8)
    print(f"{name}, {signal.Signals(sig).name} at {sum(seen.values())} times: {dict(seen)}")  # shown by pytest -rP
    if name != "corners":  # corners works for milliseconds after a second of Python starting: timing rarely hits
        assert seen["nothing written"] + seen["all written"] >= 1, seen  # the sweep hit the command at work
    # for every command, the exact steps of its commit are hit deterministically:
    ref = tmp_path / "reference" / "out"
    for step, expected in steps(name).items():
        assert at_step(tmp_path, name, ref, step) == expected, step


def test_a_signal_during_corners_leaves_its_file_whole_or_absent(tmp_path):
    seen = sweep(tmp_path, "corners", [0.7, 1.0], signal.SIGTERM)
    assert sum(seen.values()) == 2
    ref = tmp_path / "reference" / "out"
    assert at_step(tmp_path, "corners", ref, "staged:1") == "nothing written"
    assert at_step(tmp_path, "corners", ref, "renamed:1") == "all written"
