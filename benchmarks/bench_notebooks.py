"""How long each numbered notebook of the course takes to run, executed the way nbval does it.

    python benchmarks/bench_notebooks.py                      # every notebooks/[0-9][0-9]_*.ipynb
    python benchmarks/bench_notebooks.py notebooks/03_*.ipynb # some

Each notebook runs top to bottom in a fresh ``python3`` kernel with ``nbclient`` (the library
nbval runs notebooks with), from the notebook's folder. Reported: the kernel's start, the
cells' run time, and the slowest cell. Targets: each notebook under 30 s, the whole course
under 3 minutes (cells' time; kernel starts listed apart). The benchmark stops starting new
notebooks after 270 s so that it stays inside the runner's 5-minute limit, and says which
notebooks it did not time.
"""

from __future__ import annotations

import argparse
import glob
import time
from pathlib import Path

import nbformat
from nbclient import NotebookClient

ROOT = Path(__file__).resolve().parent.parent
NOTEBOOK_LIMIT_S = 30.0
COURSE_LIMIT_S = 180.0
BUDGET_S = 270.0


def run(path: Path) -> dict:
    nb = nbformat.read(path, as_version=4)
    client = NotebookClient(nb, timeout=300, kernel_name="python3", resources={"metadata": {"path": str(path.parent)}})
    cell_times = []
    t0 = time.perf_counter()
    error = ""
    with client.setup_kernel():
        started = time.perf_counter()
        for index, cell in enumerate(nb.cells):
            if cell.cell_type != "code":
                continue
            t = time.perf_counter()
            try:
                client.execute_cell(cell, index)
            except Exception as e:  # noqa: BLE001 (report the failing cell and go on with the next notebook)
                error = (
                    f"cell {index}: {type(e).__name__}: {str(e).strip().splitlines()[-1] if str(e).strip() else ''}"[
                        :200
                    ]
                )
                cell_times.append((time.perf_counter() - t, index))
                break
            cell_times.append((time.perf_counter() - t, index))
        cells_s = time.perf_counter() - started
    total = time.perf_counter() - t0
    slow_s, slow_i = max(cell_times) if cell_times else (0.0, -1)
    return dict(
        name=path.name,
        kernel=started - t0,
        cells=cells_s,
        total=total,
        n=len(cell_times),
        slow=slow_s,
        slow_index=slow_i,
        error=error,
    )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("notebooks", nargs="*", help="notebook files (default notebooks/[0-9][0-9]_*.ipynb)")
    args = ap.parse_args(argv)
    paths = [Path(p) for p in args.notebooks] or [
        Path(p) for p in sorted(glob.glob(str(ROOT / "notebooks" / "[0-9][0-9]_*.ipynb")))
    ]
    print(
        f"{len(paths)} numbered notebooks in notebooks/ ({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}); "
        "each in a fresh kernel with nbclient, as nbval runs them.\n"
    )
    print("| notebook | code cells | cells' run time | kernel start | slowest cell | under 30 s? |")
    print("|---|---|---|---|---|---|")
    t0 = time.perf_counter()
    done, skipped = [], []
    for path in paths:
        if time.perf_counter() - t0 > BUDGET_S:
            skipped.append(path.name)
            continue
        r = run(path)
        done.append(r)
        ok = "yes" if r["cells"] < NOTEBOOK_LIMIT_S and not r["error"] else "**no**"
        note = f" (stopped: {r['error']})" if r["error"] else ""
        print(
            f"| `{r['name']}` | {r['n']} | {r['cells']:.1f} s{note} | {r['kernel']:.1f} s | "
            f"{r['slow']:.1f} s (cell {r['slow_index']}) | {ok} |",
            flush=True,
        )
    course = sum(r["cells"] for r in done)
    kernels = sum(r["kernel"] for r in done)
    print(
        f"| **course** | {sum(r['n'] for r in done)} | **{course:.1f} s** | {kernels:.1f} s | | "
        f"{'yes' if course < COURSE_LIMIT_S and not skipped else '**no**'} (3 min) |"
    )
    if skipped:
        print(f"\nNot timed (the benchmark's {BUDGET_S:.0f} s budget was spent): {', '.join(skipped)}.")
    failed = [r["name"] for r in done if r["error"]]
    if failed:
        print(f"\nStopped with an error: {', '.join(failed)} (its time is up to the error).")
    print("\nThe notebooks as they are in the checkout at the date above.")
    slowest = max(done, key=lambda r: r["cells"]) if done else None
    if slowest:
        print(
            "<!-- target: course: every notebook runs in under 30 s | "
            f"slowest `{slowest['name']}` {slowest['cells']:.1f} s "
            f"({len(done)} notebooks) | {'yes' if slowest['cells'] < NOTEBOOK_LIMIT_S and not failed else '**no**'} -->"
        )
    print(
        "<!-- target: course: all numbered notebooks together in under 3 min | "
        f"{course:.0f} s for {len(done)} notebooks "
        f"(+ {kernels:.0f} s of kernel starts) | {'yes' if course < COURSE_LIMIT_S and not skipped else '**no**'} -->"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
