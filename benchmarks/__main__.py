"""Run fidlearn's benchmarks and write docs/benchmarks.md.

    python -m benchmarks                 # every benchmarks/bench_*.py
    python -m benchmarks speed pose      # some of them, by name (bench_speed.py, bench_pose.py)
    python -m benchmarks --quick         # pass --quick to the benchmarks that take it
    python -m benchmarks --list          # the names

Each benchmark runs as a subprocess of its own (``python benchmarks/bench_NAME.py``), with
a time limit (40 minutes unless ``--timeout``: the longest, survey, takes 10-11 minutes on 2 shared
cores at a load of 4, and more than 15 on a busier machine). Its printed output becomes one section of
``docs/benchmarks.md``; running some benchmarks replaces their sections and keeps the others as
they were (each section says when and by which command it was measured). The summary table "target | measured | met?" is
collected from lines ``<!-- target: what | measured | yes/no -->`` in the sections (hidden when
the page is rendered); for benchmarks that print none, from their tables (see ``_PARSERS``).
Notes written by hand between ``<!-- begin notes -->`` and ``<!-- end notes -->`` under the summary are kept.
"""

from __future__ import annotations

import argparse
import datetime as dt
import os
import platform
import re
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
DOC = ROOT / "docs" / "benchmarks.md"
TIMEOUT_S = 2400

BEGIN = "<!-- begin bench {name} -->"
END = "<!-- end bench {name} -->"
TARGET_RE = re.compile(r"^<!-- target: (.+?) \| (.+?) \| (.+?) -->$", re.M)

INTRO = """\
How fidlearn compares with plain OpenCV: accuracy against synthetic truth and real photos, speed
against OpenCV run in the same process, and the course's own run time. Written by
`{command}`; every section says when it was measured and how long it took. The benchmarks are
not part of the test suite (`make test`).

**Timings on a shared machine.** The machine was shared by several people while these numbers were
taken (load average in the table below; 2 cores). A wall-clock time then depends on who else runs.
So every speed figure is a *ratio* against plain OpenCV measured in the same process, with the two
calls interleaved call by call (fidlearn, OpenCV, fidlearn, OpenCV, ...) over many repetitions, and
the ratio is the median of the per-pair ratios: a burst of load slows both calls of a pair alike.
Where a benchmark also gives CPU time (`time.process_time`, the work done, which other processes
disturb least) it says so.
"""


def bench_files() -> dict[str, Path]:
    """``{name: path}`` of every ``benchmarks/bench_NAME.py``, sorted by name."""
    return {p.stem[len("bench_") :]: p for p in sorted(HERE.glob("bench_*.py"))}


def machine() -> list[tuple[str, str]]:
    """(what, value) rows describing this machine and the software versions."""
    cpu = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        cpu = platform.processor() or "unknown"
    ram = "unknown"
    try:
        kb = int(re.search(r"MemTotal:\s+(\d+)", Path("/proc/meminfo").read_text()).group(1))
        ram = f"{kb / 1024**2:.1f} GiB"
    except (OSError, AttributeError):
        pass
    versions = subprocess.run(
        [
            sys.executable,
            "-c",
            "import cv2, numpy, fidlearn; "
            "print(cv2.__version__, numpy.__version__, fidlearn.__version__, cv2.getNumThreads())",
        ],
        capture_output=True,
        text=True,
        cwd=ROOT,
        check=False,
    ).stdout.split()
    cv, np_version, fl, threads = (versions + ["?"] * 4)[:4]
    commit = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, cwd=ROOT, check=False
    ).stdout.strip()
    dirty = subprocess.run(
        ["git", "status", "--porcelain", "--", "fidlearn", "benchmarks"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        check=False,
    ).stdout.strip()
    return [
        ("CPU", f"{cpu}, {os.cpu_count()} cores (nproc), OpenCV threads {threads}"),
        ("RAM", ram),
        ("OS", f"{platform.system()} {platform.release()} {platform.machine()}"),
        ("Python", platform.python_version()),
        ("OpenCV", cv),
        ("NumPy", np_version),
        ("fidlearn", f"{fl}, commit {commit or '?'}{' with uncommitted changes' if dirty else ''}"),
    ]


def load_average() -> str:
    try:
        return ", ".join(f"{v:.1f}" for v in os.getloadavg())
    except OSError:
        return "unknown"


def looks_like_markdown(text: str) -> bool:
    """Output with a markdown table (a ``|---|`` line) or headings is kept as it is; else it goes in a code block."""
    return bool(re.search(r"^\|[-:| ]+\|\s*$", text, re.M) or re.search(r"^#{2,4} ", text, re.M))


def tidy_markdown(text: str) -> str:
    """Printed output that holds markdown tables, made to render: a blank line around each table,
    indented runs of lines in a code block, and every other line its own paragraph (a benchmark
    prints one statement per line; markdown would run them together)."""
    out: list[str] = []
    block = None  # "table", "code" or None
    for line in text.splitlines():
        kind = "table" if line.startswith("|") else ("code" if line.startswith("  ") and line.strip() else None)
        if kind != block:
            if block == "code":
                out.append("```")
            if out and out[-1] != "":
                out.append("")
            if kind == "code":
                out.append("```")
            block = kind
        elif kind is None and line.strip() and out and out[-1] != "" and not line.startswith(("<!--", "- ", "* ")):
            out.append("")
        out.append(line)
    if block == "code":
        out.append("```")
    return re.sub(r"\n{3,}", "\n\n", "\n".join(out))


def run_one(name: str, path: Path, quick: bool, timeout: float) -> dict:
    """Run one benchmark; its output, status, seconds and the command."""
    cmd = [sys.executable, str(path.relative_to(ROOT))]
    if quick and "--quick" in path.read_text():
        cmd.append("--quick")
    env = dict(os.environ, PYTHONUNBUFFERED="1")  # what was printed before a timeout is kept
    t0 = time.perf_counter()
    started = dt.datetime.now(dt.timezone.utc)
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=ROOT, env=env, check=False)
        out, err, status = (
            proc.stdout,
            proc.stderr,
            ("ok" if proc.returncode == 0 else f"failed (exit status {proc.returncode})"),
        )
    except subprocess.TimeoutExpired as e:
        out = e.stdout.decode() if isinstance(e.stdout, bytes) else (e.stdout or "")
        err = e.stderr.decode() if isinstance(e.stderr, bytes) else (e.stderr or "")
        status = f"stopped after the {timeout:.0f} s limit"
    seconds = time.perf_counter() - t0
    return dict(
        name=name,
        cmd=" ".join(["python", *cmd[1:]]),
        out=out.rstrip(),
        err=err.rstrip(),
        status=status,
        seconds=seconds,
        started=started,
        load=load_average(),
    )


def section(result: dict) -> str:
    """The markdown section of one benchmark run, targets included as hidden comment lines."""
    name, out = result["name"], result["out"]
    lines = [BEGIN.format(name=name), f"## {name} (`benchmarks/bench_{name}.py`)", ""]
    lines.append(
        f"`{result['cmd']}`, {result['started']:%Y-%m-%d %H:%M} UTC, {result['seconds']:.0f} s, "
        f"load average {result['load']} at the end; {result['status']}."
    )
    lines.append("")
    if out:
        if looks_like_markdown(out):
            lines.append(tidy_markdown(out))
        else:
            lines += ["```", out, "```"]
    if result["status"] != "ok" and result["err"]:
        tail = "\n".join(result["err"].splitlines()[-15:])
        lines += ["", "Error output (last lines):", "", "```", tail, "```"]
    own = TARGET_RE.findall(out)
    if not own and name in _PARSERS:
        try:
            rows = _PARSERS[name](out)
        except Exception as e:  # noqa: BLE001 (a parser that no longer fits the output must not stop the run)
            rows = [(f"{name}: targets", f"could not be read from the output ({type(e).__name__})", "?")]
        lines += [""] + [f"<!-- target: {a} | {b} | {c} -->" for a, b, c in rows]
    lines.append(END.format(name=name))
    return "\n".join(lines)


def old_sections(text: str) -> dict[str, str]:
    """The sections of an existing docs/benchmarks.md, by benchmark name."""
    out = {}
    for m in re.finditer(r"<!-- begin bench (\w+) -->.*?<!-- end bench \1 -->", text, re.S):
        out[m.group(1)] = m.group(0)
    return out


def summary(sections: dict[str, str]) -> str:
    rows = []
    for name, text in sections.items():
        for what, measured, met in TARGET_RE.findall(text):
            rows.append(f"| {what} | {measured} | {met} | [{name}](#{name}-benchmarksbench_{name}py) |")
    if not rows:
        return "No benchmark reported a target."
    return "\n".join(["| target | measured | met? | section |", "|---|---|---|---|", *rows])


NOTES_RE = re.compile(r"<!-- begin notes -->.*?<!-- end notes -->", re.S)
NOTES_EMPTY = "<!-- begin notes -->\n<!-- end notes -->"


def old_notes(text: str) -> str:
    """The hand-written notes on the targets (kept from run to run), or an empty block."""
    m = NOTES_RE.search(text)
    return m.group(0) if m else NOTES_EMPTY


def write_doc(sections: dict[str, str], command: str, ran: list[dict], notes: str = NOTES_EMPTY) -> Path:
    from fidlearn._io import write_text_atomic  # noqa: PLC0415 (importing fidlearn is the benchmarks' business)

    now = dt.datetime.now(dt.timezone.utc)
    head = [
        "# Benchmarks",
        "",
        INTRO.format(command=command),
        "## Machine and versions",
        "",
        "| | |",
        "|---|---|",
        *[f"| {a} | {b} |" for a, b in machine()],
        f"| date | {now:%Y-%m-%d %H:%M} UTC (this run: {', '.join(r['name'] for r in ran)}) |",
        f"| load average (1, 5, 15 min) | {load_average()} at the end of this run |",
        "",
        "## Summary: targets",
        "",
        summary(sections),
        "",
        notes,
        "",
    ]
    body = [sections[k] for k in sorted(sections)]
    return write_text_atomic(DOC, "\n".join(head) + "\n" + "\n\n".join(body) + "\n")


# ------------------------------------------------------------------------------------------------
# Targets read from the tables of benchmarks that do not print target lines themselves
# ------------------------------------------------------------------------------------------------


def _yes(ok: bool) -> str:
    return "yes" if ok else "**no**"


def _parse_pose(out: str) -> list[tuple[str, str, str]]:
    rows = []
    m = re.search(r"median locate\[default\] / median seed.*?= ([\d.]+)", out)
    if m:
        r = float(m.group(1))
        rows.append(
            (
                "pose: median camera-position error of `locate` <= 0.5 x the seed pipeline's (rendered scenes)",
                f"{r:.3f} x",
                _yes(r <= 0.5),
            )
        )
    ratios = []
    block = out.split("== 2.", 1)[1].split("== 3.", 1)[0] if "== 2." in out else ""
    for line in block.splitlines():
        nums = re.findall(r"-?\d+\.\d+", line)
        if re.match(r"^\S.*\d", line) and len(nums) >= 4 and not line.startswith("("):
            ratios.append(float(nums[3]))
    if ratios:
        worst = max(ratios, key=lambda v: abs(v - 1))
        rows.append(
            (
                "optimality: median NEES within 10 % of LM started at the truth (every scene and noise)",
                f"ratio {min(ratios):.2f} to {max(ratios):.2f}",
                _yes(abs(worst - 1) <= 0.10),
            )
        )
    cov = (
        [float(v) for v in re.findall(r":\s+([\d.]+) % of \d+", out.split("== 3.", 1)[1].split("== 4.", 1)[0])]
        if "== 3." in out
        else []
    )
    if cov:
        rows.append(
            (
                "covariance: 90-98 % of true positions inside the 95 % ellipsoid",
                f"{min(cov):.1f} to {max(cov):.1f} %",
                _yes(min(cov) >= 90 and max(cov) <= 98),
            )
        )
    m = re.search(r"^locate\[default\]\s+[\d.]+ ms\s+([\d.]+) x plain", out, re.M)
    if m:
        r = float(m.group(1))
        rows.append(
            (
                "pose section's speed: `locate` <= 1.10 x plain detectMarkers (640x480)",
                f"{r:.2f} x",
                "yes" if r <= 1.10 else ("within the 1.25 x limit" if r <= 1.25 else "**no**"),
            )
        )
    return rows


def _parse_corners(out: str) -> list[tuple[str, str, str]]:
    table = out.split("Corner error [px]", 1)[1].split("Mean image-frame offset", 1)[0]
    header = next(line for line in table.splitlines() if line.startswith("| side px"))
    methods = [c.strip() for c in header.strip("|").split("|")][1:]
    col = methods.index("edges") if "edges" in methods else 0
    worst = 0.0
    for line in table.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if not cells or not cells[0].isdigit() or int(cells[0]) < 30:
            continue
        cell = cells[1 + col]
        if cell != "-":
            worst = max(worst, float(cell.split("/")[0]))
    return [
        (
            f"corners: RMS <= 0.3 px for markers >= 30 px (default refinement `{methods[col]}`)",
            f"{worst:.3f} px at worst",
            _yes(worst <= 0.3),
        )
    ]


_CALIBRATION_SPEED_RE = re.compile(
    r"^\s+(checkerboard\+std|checkerboard|charuco-rendered|charuco-photos)\s+(\d+)\s+[\d.]+\s+[\d.]+\s+([\d.]+)\s+([\d.]+)\s*$",
    re.M,
)
_CALIBRATION_SPEED_WHAT = {
    "checkerboard": "calibration: `calibrate_checkerboard` <= 1.10 x plain find + subpix + calibrateCamera, {n} views",
    "checkerboard+std": "calibration: the same with `std_intrinsics` read, <= 1.10 x, {n} views",
    "charuco-rendered": "calibration: `calibrate_charuco` <= 1.10 x plain CharucoDetector + calibrateCamera, {n} views",
    "charuco-photos": "calibration: `calibrate_charuco` <= 1.10 x plain CharucoDetector + calibrateCamera, {n} photos",
}


def _parse_calibration(out: str) -> list[tuple[str, str, str]]:
    rows = []
    if "1. Synthetic views" in out:
        errs = []
        for line in out.split("1. Synthetic views", 1)[1].split("2. Corner finders", 1)[0].splitlines():
            nums = line.split()
            if len(nums) >= 4 and nums[1] == "20":
                errs.append(float(nums[2]))
        rows.append(
            (
                "calibration: fx error with 20 views (synthetic, no target set)",
                f"{min(errs):.3f} to {max(errs):.3f} %",
                "see section",
            )
        )
    speed = out.split("4. Speed against plain OpenCV", 1)[1] if "4. Speed against plain OpenCV" in out else ""
    for label, n, wall, cpu in _CALIBRATION_SPEED_RE.findall(speed):
        w, c = float(wall), float(cpu)
        rows.append(
            (
                _CALIBRATION_SPEED_WHAT[label].format(n=n),
                f"{w:.2f} x wall, {c:.2f} x CPU",
                _yes(w <= 1.10 and c <= 1.10),
            )
        )
    return rows


_PARSERS = {
    "pose": _parse_pose,
    "corners": _parse_corners,
    "calibration": _parse_calibration,
}


def main(argv=None) -> int:
    files = bench_files()
    ap = argparse.ArgumentParser(prog="python -m benchmarks", description=__doc__.splitlines()[0])
    ap.add_argument("names", nargs="*", help=f"benchmarks to run (default all: {', '.join(files)})")
    ap.add_argument("--quick", action="store_true", help="pass --quick to the benchmarks that take it")
    ap.add_argument(
        "--timeout", type=float, default=TIMEOUT_S, help=f"seconds each benchmark may take (default {TIMEOUT_S:.0f})"
    )
    ap.add_argument("--list", action="store_true", help="list the benchmarks and stop")
    ap.add_argument("--no-doc", action="store_true", help="print the sections instead of writing docs/benchmarks.md")
    args = ap.parse_args(argv)
    if args.list:
        print("\n".join(files))
        return 0
    unknown = [n for n in args.names if n.removeprefix("bench_").removesuffix(".py") not in files]
    if unknown:
        ap.error(f"no benchmark {', '.join(unknown)}; there are: {', '.join(files)}")
    names = [n.removeprefix("bench_").removesuffix(".py") for n in args.names] or list(files)
    command = (
        " ".join(["python -m benchmarks", *sys.argv[1:]]) if argv is None else " ".join(["python -m benchmarks", *argv])
    )
    old = DOC.read_text() if DOC.exists() else ""
    sections = old_sections(old)
    notes = old_notes(old)
    ran = []
    failed = 0
    for name in names:
        print(f"[benchmarks] {name} ...", flush=True)
        result = run_one(name, files[name], args.quick, args.timeout)
        ran.append(result)
        failed += result["status"] != "ok"
        print(f"[benchmarks] {name}: {result['status']} in {result['seconds']:.0f} s", flush=True)
        sections[name] = section(result)
        if args.no_doc:
            print(sections[name])
        else:
            write_doc(
                {k: v for k, v in sections.items() if k in files}, command, ran, notes
            )  # after each, so a stop keeps what ran
    if not args.no_doc:
        print(f"[benchmarks] wrote {DOC.relative_to(ROOT)}")
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
