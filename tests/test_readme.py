"""Every command in README.md and docs/teaching.md runs as written, and every output they show is what prints.

The commands run in order, as a new user types them after ``make lab`` or ``make test``: in a
fresh copy of the repository (the files git tracks), with this test's own Python environment
as ``.venv``. Every line of an output block (a plain fence after a command block) must be a
line the commands printed, so a number shown in the documents can never go stale. The few
commands that cannot run here are listed in ``EXCLUDED``, each with its reason, and that
list is checked too: each entry must match a documented command.
"""

from __future__ import annotations

import csv
import os
import re
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import pytest

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
TEACHING = ROOT / "docs" / "teaching.md"

#: Commands that do not run here, each with its reason. Each pattern must match a documented command.
EXCLUDED = {
    r"^make lab\b": "starts JupyterLab and a browser, and serves until stopped",
    r"^make test\b": "runs the whole test suite, this test included",
    r"--camera-index 0\b": "reads a live camera, which a test machine does not have",
    r"--live\b": "serves the live view to Foxglove until Ctrl-C (tests/test_ros_bag.py connects to it)",
    r"^\.venv/bin/python tools/make_student_copies\.py\s*(#|$)": (
        "rebuilds and executes every exercise notebook (minutes); tests/test_exercise_notebooks.py "
        "checks that the stored ones are current, as the --check the guide runs first does"
    ),
    r"^\.venv/bin/python -m pytest tests/": "runs part of the test suite, which make test runs",
}
#: The documents show what OpenCV 5 prints (as the notebooks' stored outputs); other releases may
#: differ in the last digit (make test-cv4, make test-floor).
REFERENCE = cv2.__version__.split(".")[0] == "5"
#: Options whose value is a file or folder that the command promises to write.
OUTPUT_OPTIONS = ("-o", "--output", "--new-secret", "--json", "--annotate", "--truth", "--plot", "--report", "--ros")
#: The first word of a command in an untagged fence (the grading guide's blocks have no language).
SHELL_START = re.compile(r"^(fidlearn|\.venv/|FIDLEARN_\w+=|make|python|source|mkdir|cd|pip)\b")
#: The learners of the roster the grading steps are tried with.
LEARNERS = ("alice",)


@dataclass
class Fence:
    lang: str
    text: str
    line: int
    outputs: list[str] = field(default_factory=list)  # the plain fences that follow a command block


def fences(path: Path) -> list[Fence]:
    """Every fenced block of a Markdown file, in order."""
    found, lang, start, indent, body = [], None, 0, 0, []
    for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        stripped = line.strip()
        if lang is None and stripped.startswith("```"):
            lang, start, indent, body = stripped[3:].strip(), n, len(line) - len(line.lstrip()), []
        elif lang is not None and stripped == "```":
            found.append(Fence(lang, "\n".join(body), start))
            lang = None
        elif lang is not None:  # a fence inside a list item: its lines lose the item's indent
            body.append(line[indent:] if not line[:indent].strip() else line.lstrip())
    return found


def is_shell(fence: Fence) -> bool:
    if fence.lang in ("bash", "sh", "shell"):
        return True
    first = next((line for line in fence.text.splitlines() if line.strip()), "")
    return fence.lang == "" and bool(SHELL_START.match(first.strip()))


def command_blocks(path: Path) -> list[Fence]:
    """The shell blocks, each with the output blocks (plain fences that are not commands) after it."""
    blocks: list[Fence] = []
    for fence in fences(path):
        if is_shell(fence):
            blocks.append(fence)
        elif fence.lang in ("", "text") and blocks:
            blocks[-1].outputs.append(fence.text)
    return blocks


def commands(block: Fence) -> list[str]:
    """The block's commands, continuation lines joined."""
    return [c.strip() for c in block.text.replace("\\\n", " ").splitlines() if c.strip()]


def excluded(command: str) -> str | None:
    return next((why for pattern, why in EXCLUDED.items() if re.search(pattern, command)), None)


def promised_outputs(command: str) -> list[str]:
    words = shlex.split(command, comments=True)
    return [words[k + 1] for k, w in enumerate(words[:-1]) if w in OUTPUT_OPTIONS]


# -- the copy and the environment ------------------------------------------------------------------


def fresh_copy(dest: Path) -> Path:
    """The files git tracks (as they are in the working tree), as a fresh clone holds them."""
    listed = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True).stdout
    for rel in filter(None, listed.decode().split("\0")):
        src = ROOT / rel
        if src.is_file():
            (dest / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / rel)
    bindir = Path(sys.executable).parent
    if (bindir / "activate").is_file():
        (dest / ".venv").symlink_to(bindir.parent, target_is_directory=True)
    else:  # not a virtualenv (conda, a system Python): .venv/bin holds the same commands and an activate
        (dest / ".venv" / "bin").mkdir(parents=True)
        (dest / ".venv" / "bin" / "activate").write_text(f'export PATH="{bindir}:$PATH"\n')
        for name in ("python", "fidlearn"):
            (dest / ".venv" / "bin" / name).symlink_to(bindir / name)
    return dest


def environment(copy: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("FIDLEARN_", "PYTEST_"))}
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    env["PYTHONPATH"] = str(copy)  # the copy's fidlearn, as a fresh clone's editable install gives
    env["MPLBACKEND"] = "Agg"
    env["HOME"] = str(copy.parent / "home")
    Path(env["HOME"]).mkdir(exist_ok=True)
    return env


MARK = "@@fidlearn-doc-block"


def run_blocks(copy: Path, blocks: list[Fence], prepare=None) -> list[str]:
    """Run every block in one shell (``source`` carries over), stopping at the first failure.

    Returns the output (stdout and stderr) of each block. ``prepare(command)`` returns the shell
    lines that run the command: what the guide asks a person to do by hand before it, then the
    command.
    """
    script = ["set -e -o pipefail", "exec 2>&1"]
    for k, block in enumerate(blocks):
        script.append(f"printf '\\n{MARK} {k}@@\\n'")
        for command in commands(block):
            why = excluded(command)
            if why:
                script.append(f": excluded, {shlex.quote(why)}")
                continue
            script.extend(prepare(command) if prepare else [command])
    script.append(f"printf '\\n{MARK} end@@\\n'")
    proc = subprocess.run(
        ["bash", "-c", "\n".join(script)],
        cwd=copy,
        env=environment(copy),
        capture_output=True,
        text=True,
        timeout=900,
        stdin=subprocess.DEVNULL,
    )
    parts = re.split(rf"\n{MARK} (\d+|end)@@\n", "\n" + proc.stdout)
    ran, printed = parts[1::2], parts[2::2]
    if proc.returncode != 0 or not ran or ran[-1] != "end":
        where = f"the block at line {blocks[int(ran[-1])].line}" if ran and ran[-1] != "end" else "the script"
        pytest.fail(f"{where} failed (exit status {proc.returncode}):\n{proc.stdout[-4000:]}")
    return printed[:-1]


def normal(line: str) -> str:
    return " ".join(line.split())


NUMBER = re.compile(r"-?\d+(?:\.(\d+))?")


def close_enough(shown: str, printed: str) -> bool:
    """The same words, and every number within 3 units of its last shown digit or 2 %."""
    if NUMBER.sub("#", normal(shown)) != NUMBER.sub("#", normal(printed)):
        return False
    for a, b in zip(NUMBER.finditer(shown), NUMBER.finditer(printed)):
        unit = 10.0 ** -len(a[1] or "")
        if abs(float(a[0]) - float(b[0])) > max(3 * unit, 0.02 * abs(float(a[0]))):
            return False
    return True


def stale_lines(shown: str, printed: str, exact: bool = True) -> list[str]:
    """The lines of an output block that were not printed (``...`` stands for lines left out).

    ``exact=False`` (another OpenCV than the one that made the documents' outputs, as nbval-lax
    for the notebooks) lets the last digits differ (:func:`close_enough`), never the words.
    """
    printed_lines = {normal(line) for line in printed.splitlines()}
    missing = []
    for line in shown.splitlines():
        if normal(line) in ("", "...") or normal(line) in printed_lines:
            continue
        if not exact and any(close_enough(line, p) for p in printed.splitlines()):
            continue
        first = line.split()[0]
        near = [p for p in printed.splitlines() if p.split()[:1] == [first]]
        missing.append(f"shown:   {line}\n  printed: {near[0] if near else '(no such line)'}")
    return missing


def check_outputs(blocks: list[Fence], outputs: list[str], doc: str) -> int:
    stale, compared = [], 0
    for block, printed in zip(blocks, outputs):
        for shown in block.outputs:
            compared += len([line for line in shown.splitlines() if normal(line) not in ("", "...")])
            stale += [f"{doc} line {block.line}: {m}" for m in stale_lines(shown, printed, exact=REFERENCE)]
    assert stale == [], "\n".join(stale)
    return compared


def check_promised(copy: Path, blocks: list[Fence], skip=lambda _command: False) -> list[str]:
    made = []
    for block in blocks:
        for command in commands(block):
            if excluded(command) or skip(command) and "--new-secret" not in command:
                continue
            for out in promised_outputs(command):
                path = copy / out
                assert path.exists(), f"{command!r} did not write {out}"
                assert not path.is_dir() or any(path.iterdir()), f"{command!r} left {out} empty"
                made.append(out)
    return made


# -- what the documents hold -------------------------------------------------------------------------


def test_the_readme_has_its_commands_and_outputs():
    blocks = command_blocks(README)
    runnable = [c for b in blocks for c in commands(b) if not excluded(c)]
    assert len(runnable) >= 12
    assert sum(len(b.outputs) for b in blocks) >= 5
    for command in runnable:  # no file outside the repository, nothing written outside out/
        words = shlex.split(command, comments=True)
        for out in promised_outputs(command):
            assert out.startswith("out/"), command
        for word in words[1:]:
            if re.fullmatch(r"[\w./-]+\.(png|jpg|json|mp4|yml|yaml)|[\w-]+/", word) and not word.startswith("out/"):
                assert (ROOT / word).exists(), f"{command!r}: {word} is not in the repository"


def test_every_exclusion_matches_a_documented_command():
    documented = [c for path in (README, TEACHING) for b in command_blocks(path) for c in commands(b)]
    for pattern, why in EXCLUDED.items():
        assert why, pattern
        assert any(re.search(pattern, c) for c in documented), pattern
    assert excluded("fidlearn locate --camera-index 0 --camera c.json --map m.json") is not None
    assert excluded("fidlearn locate data/scenes --camera c.json --map m.json") is None
    assert excluded(".venv/bin/python tools/make_student_copies.py --check") is None


def test_the_output_check_sees_a_stale_number():
    printed = "frame   x_mm\nscene_00.png   999.9   229.6\n10 frames\n"
    assert stale_lines("frame x_mm\nscene_00.png 999.9 229.6\n...", printed) == []
    [stale] = stale_lines("scene_00.png 999.9 229.8\n...", printed)
    assert "229.8" in stale
    assert "printed: scene_00.png   999.9   229.6" in stale
    # on another OpenCV release the last digits may move, not the words nor the numbers' size
    assert stale_lines("scene_00.png 999.9 229.8", printed, exact=False) == []
    assert len(stale_lines("scene_00.png 999.9 235.1", printed, exact=False)) == 1
    assert len(stale_lines("scene_00.png 999.9 229.8 px", printed, exact=False)) == 1
    assert close_enough("rms 0.04 px", "rms 0.06 px")
    assert not close_enough("rms 0.04 px", "rms 0.08 px")


# -- running them ----------------------------------------------------------------------------------


@pytest.mark.slow
def test_every_readme_command_runs_and_prints_what_the_readme_shows(tmp_path):
    copy = fresh_copy(tmp_path / "fidlearn")
    blocks = command_blocks(README)
    outputs = run_blocks(copy, blocks)
    assert len(outputs) == len(blocks)
    assert check_outputs(blocks, outputs, "README.md") >= 10
    made = check_promised(copy, blocks)
    assert {"out/board.pdf", "out/camera.json", "out/poses.jsonl", "out/track.txt"} <= set(made)
    # only out/ was written: the repository's own files are as git holds them
    status = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True).stdout
    tracked = {Path(p) for p in status.decode().split("\0") if p}
    new = {
        p.relative_to(copy)
        for p in copy.rglob("*")
        if p.is_file() and ".venv" not in p.relative_to(copy).parts and "__pycache__" not in p.parts
    }
    assert {p for p in new - tracked if p.parts[0] != "out"} == set()


def test_the_readme_library_snippet_prints_what_it_shows(tmp_path):
    [snippet] = [f for f in fences(README) if f.lang == "python"]
    shown = [line.split("#", 1)[1].strip() for line in snippet.text.splitlines() if line.startswith("print(")]
    assert shown
    assert all(s.endswith("...)") for s in shown)
    proc = subprocess.run(
        [sys.executable, "-c", snippet.text],
        cwd=fresh_copy(tmp_path / "fidlearn"),
        env=environment(tmp_path / "fidlearn"),
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    printed = proc.stdout.splitlines()
    assert len(printed) == len(shown)
    for want, got in zip(shown, printed):
        head = want.removesuffix("...)")
        if REFERENCE:
            assert got.startswith(head), f"shown: {want}\nprinted: {got}"
        else:  # the same words and numbers, the last digits free (see stale_lines)
            words = len(head.split())
            assert close_enough(head, " ".join(got.split()[:words])), f"shown: {want}\nprinted: {got}"


# -- the teaching guide ------------------------------------------------------------------------------


def prepare_by_hand(copy: Path):
    """What the guide asks the instructor to do between two commands, done before the command needs it."""
    released: list[str] = []

    def run(command: str) -> list[str]:
        lines = []
        words = shlex.split(command, comments=True)
        if words[:2] == ["fidlearn", "release"]:
            released.extend(promised_outputs(command))
        for word in words:
            if "roster" in word and not (copy / word).exists():  # "write the roster"
                lines.append(f"printf '%s\\n' {' '.join(LEARNERS)} > {shlex.quote(word)}")
            m = re.fullmatch(r"submissions/(\w+)/(\d\d_\w+\.ipynb)", word)
            if m:  # a learner's own answered notebook: the lesson's answer key stands in for it
                lines.append(f"mkdir -p submissions/{m[1]}")
                lines.append(f"cp notebooks/exercises/solutions/{m[2]} {shlex.quote(word)}")
        if words[:2] == ["fidlearn", "grade"] and any(w.startswith("submissions/") for w in words):
            # "collect the notebooks as submissions/<learner id>.ipynb" from the released folders
            lines.append("mkdir -p submissions")
            lines += [f"cp {released[-1]}/{who}/*.ipynb submissions/{who}.ipynb" for who in LEARNERS]
        return [*lines, command]

    return run


@pytest.mark.slow
def test_every_teaching_guide_command_runs(tmp_path):
    copy = fresh_copy(tmp_path / "fidlearn")
    blocks = command_blocks(TEACHING)
    assert len(blocks) >= 4
    outputs = run_blocks(copy, blocks, prepare_by_hand(copy))
    check_outputs(blocks, outputs, "docs/teaching.md")
    made = check_promised(copy, blocks)
    documented = " ".join(c for b in blocks for c in commands(b))
    if "fidlearn release" in documented:
        release = next(Path(m) for m in made if m.startswith("release"))
        for who in LEARNERS:
            assert list((copy / release / who).glob("*.ipynb")), f"no notebook for {who}"
            assert (copy / release / who / "fidlearn_inputs.json").is_file()
    for grades in (copy / m for m in made if m.endswith(".csv")):
        rows = list(csv.DictReader(grades.open(encoding="utf-8")))
        assert {row["learner"] for row in rows} == set(LEARNERS)


def test_the_teaching_table_covers_every_lesson():
    """One row per numbered notebook, with its times; a lesson with exercises names its exercise notebook."""
    text = TEACHING.read_text(encoding="utf-8")
    table = text.split("## The course in one table", 1)[1].split("\n## ", 1)[0]
    rows = {r.split("|")[1].strip(): r for r in table.splitlines() if re.match(r"\| \d\d \|", r)}
    notebooks = sorted(p.name[:2] for p in (ROOT / "notebooks").glob("[0-9][0-9]_*.ipynb"))
    assert notebooks[0] == "00"
    assert len(notebooks) >= 13
    assert sorted(rows) == notebooks
    for number, row in rows.items():
        cells = [c.strip() for c in row.strip().strip("|").split("|")]
        assert re.fullmatch(r"\d+ min", cells[3]), row  # the story's time
        story = next((ROOT / "notebooks").glob(f"{number}_*.ipynb")).stem
        assert cells[1] in (f"`{story}`", f"`{number}_*`"), row
        lessons = list((ROOT / "fidlearn" / "exercises" / "lessons").glob(f"l{number}_*.py"))
        if lessons:
            topic = lessons[0].stem.split("_", 1)[1]
            assert cells[2].startswith(f"`{number}_{topic}`"), row
            assert re.fullmatch(r"\d+ min", cells[4]), row
            assert (ROOT / "notebooks" / "exercises" / f"{number}_{topic}.ipynb").is_file()
