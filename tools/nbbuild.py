"""Build the course notebooks from their plain-Python sources, and check that they are up to date.

A notebook is written as a "percent" script, ``notebooks/src/NN_topic.py``::

    # %% [markdown]
    # # 03 Extrinsics
    # What you will learn: ...

    # %%
    import numpy as np
    print(np.eye(2))

* ``# %%`` starts a code cell, ``# %% [markdown]`` a markdown cell whose lines
  are ``# ``-prefixed comments (the prefix is removed).
* In a code cell a line ``# %matplotlib inline`` (a comment, so the script
  stays valid Python) becomes the IPython magic ``%matplotlib inline``.
* A code cell whose output truly varies (a live widget, a version number)
  starts with ``# NBVAL_IGNORE_OUTPUT``: nbval then runs it without comparing.
* Anything before the first ``# %%`` must be blank or comments; it is ignored
  (a place for a licence line or a note to authors).
* A number in the prose comes from the code, never typed by hand: in a markdown
  cell, ``{{ expr }}`` or ``{{ expr:spec }}`` (a format spec such as ``.2f``)
  is evaluated in the kernel when the build reaches that cell, with the names the
  cells above it made, and replaced by ``format(expr, spec)``. The notebook
  stores the rendered text (what a learner reads) and keeps the template in the
  cell's metadata (``fidlearn.template``), so ``--check`` compares the template
  with the source, and a changed output can never leave a stale number in the
  sentence that cites it.

``notebooks/src/NN_topic.py`` builds ``notebooks/NN_topic.ipynb`` (in general:
``<dir>/src/<name>.py`` builds ``<dir>/<name>.ipynb``), executed top to bottom
by nbclient with the ``python3`` kernel and the notebook's own folder as the
working directory, so every stored output is a real output of the committed
code. Execution metadata (timestamps), widget model ids and random cell ids are
left out so rebuilding an unchanged source gives an unchanged file.

Usage::

    python tools/nbbuild.py notebooks/src/03_extrinsics_transforms.py   # build one (or several)
    python tools/nbbuild.py --all                                       # build every source
    python tools/nbbuild.py --check                                     # exit 1 if a notebook is stale

``--check`` does not run anything: it compares each notebook's cells with its
source and verifies that every code cell has been executed without an error.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import time
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
NOTEBOOKS = REPO / "notebooks"
KERNEL_NAME = "python3"
#: Longest single wait for a message on the kernel's shell channel (see :func:`read_in_steps`).
SHELL_STEP_S = 1.0
#: Seconds one cell may run before the build fails.
CELL_TIMEOUT_S = 600

_CELL_MARK = re.compile(r"^# %%(?P<rest>(\s.*)?)$")
_MAGIC = re.compile(r"^# (?P<magic>%{1,2}[A-Za-z].*)$")
_WIDGET_MIME = "application/vnd.jupyter.widget-view+json"
#: ``{{ expr }}`` or ``{{ expr:spec }}`` in a markdown cell: a value from the kernel.
_FIELD = re.compile(r"\{\{(?P<body>.+?)\}\}", re.DOTALL)
_SPEC = re.compile(r"^[<>=^]?[+\- ]?#?0?\d*[,_]?(\.\d+)?[bcdeEfFgGnosxX%]?$")
#: Where a rendered markdown cell keeps its template.
TEMPLATE_KEY = "fidlearn"


class BuildError(Exception):
    """A source that cannot be turned into a notebook, or a notebook that does not run."""


@dataclass(frozen=True)
class Cell:
    """One cell parsed from a percent script: ``kind`` is ``"code"`` or ``"markdown"``."""

    kind: str
    source: str


# -- parsing ---------------------------------------------------------------------------
def parse_percent(text: str, where: str = "<source>") -> list[Cell]:
    """Cells of a percent script, in order (empty cells are dropped)."""
    cells: list[Cell] = []
    kind: str | None = None
    lines: list[str] = []

    def flush(lineno: int) -> None:
        if kind is None:
            stray = [ln for ln in lines if ln.strip() and not ln.lstrip().startswith("#")]
            if stray:
                raise BuildError(
                    f"{where}: code before the first '# %%' line ({stray[0].strip()!r}); "
                    "start every cell with '# %%' or '# %% [markdown]'"
                )
            return
        body = list(lines)
        while body and not body[0].strip():
            body.pop(0)
        while body and not body[-1].strip():
            body.pop()
        if kind == "markdown":
            out = []
            for i, ln in enumerate(body):
                if ln.startswith("# "):
                    out.append(ln[2:])
                elif ln.rstrip() == "#" or not ln.strip():
                    out.append("")
                else:
                    raise BuildError(
                        f"{where}: line {lineno - len(lines) + i}: a markdown cell's lines must start with '# ', "
                        f"got {ln!r}"
                    )
            body = out
        else:
            body = [(_MAGIC.match(ln).group("magic") if _MAGIC.match(ln) else ln) for ln in body]
        if body:
            cells.append(Cell(kind, "\n".join(body)))

    for lineno, line in enumerate(text.splitlines(), start=1):
        m = _CELL_MARK.match(line)
        if m:
            flush(lineno)
            rest = m.group("rest").strip()
            if rest in ("", "[code]"):
                kind = "code"
            elif rest == "[markdown]" or rest == "[md]":
                kind = "markdown"
            else:
                raise BuildError(
                    f"{where}: line {lineno}: unknown cell marker {line!r}; use '# %%' or '# %% [markdown]'"
                )
            lines = []
        else:
            lines.append(line)
    flush(len(text.splitlines()) + 1)
    if not cells:
        raise BuildError(f"{where}: no cells; a notebook source starts its cells with '# %%' lines")
    return cells


def prose_fields(markdown: str) -> list[tuple[str, str]]:
    """The ``(expr, spec)`` of every ``{{ expr:spec }}`` field in a markdown cell, in order.

    The spec is the text after the last ``:`` when it is a format spec (``.2f``, ``,``, ``.1%``),
    so an expression may hold colons of its own (``x[1:3]``).
    """
    fields = []
    for m in _FIELD.finditer(markdown):
        body = m.group("body").strip()
        expr, _, spec = body.rpartition(":")
        if not expr or not _SPEC.match(spec.strip()):
            expr, spec = body, ""
        fields.append((expr.strip(), spec.strip()))
    return fields


def render_prose(markdown: str, values: list[str]) -> str:
    """``markdown`` with its fields replaced, in order, by ``values``."""
    it = iter(values)
    return _FIELD.sub(lambda _m: next(it), markdown)


def _field_code(fields: list[tuple[str, str]]) -> str:
    """Code that prints the formatted fields as one JSON list (run without touching the kernel's history)."""
    items = ", ".join(f"format(({expr}), {spec!r})" for expr, spec in fields)
    return f"print(__import__('json').dumps([{items}]))"


def notebook_path(src: Path) -> Path:
    """Where a source builds to: ``<dir>/src/<name>.py`` -> ``<dir>/<name>.ipynb``."""
    src = Path(src)
    if src.parent.name != "src" or src.suffix != ".py":
        raise BuildError(
            f"{src}: a notebook source lives in a 'src' folder and ends in .py (notebooks/src/NN_topic.py)"
        )
    return src.parent.parent / (src.stem + ".ipynb")


def all_sources() -> list[Path]:
    """Every notebook source under ``notebooks/`` (``notebooks/src/*.py``, ``notebooks/*/src/*.py``)."""
    found = sorted(NOTEBOOKS.glob("src/*.py")) + sorted(NOTEBOOKS.glob("*/src/*.py"))
    return [p for p in found if not p.name.startswith("_")]


# -- building --------------------------------------------------------------------------
def make_notebook(cells: list[Cell]):
    """An unexecuted nbformat notebook with stable cell ids."""
    import nbformat

    nb = nbformat.v4.new_notebook()
    for i, cell in enumerate(cells):
        if cell.kind == "markdown":
            c = nbformat.v4.new_markdown_cell(cell.source)
        else:
            c = nbformat.v4.new_code_cell(cell.source)
        c["id"] = f"cell-{i:03d}"
        nb.cells.append(c)
    nb.metadata = {
        "kernelspec": {"display_name": "Python 3 (ipykernel)", "language": "python", "name": KERNEL_NAME},
        "language_info": {"name": "python"},
    }
    return nb


def _stabilise(nb) -> None:
    """Drop what changes from run to run without the source changing."""
    nb.metadata.pop("widgets", None)
    nb.metadata["language_info"] = {"name": "python"}
    for cell in nb.cells:
        cell.metadata.pop("execution", None)
        if cell.cell_type != "code":
            continue
        kept = []
        for out in cell.outputs:
            data = out.get("data")
            if data is not None and _WIDGET_MIME in data:
                data.pop(_WIDGET_MIME)  # a random model id; the text/plain form stays
                if not data:
                    continue
            if out.get("output_type") in ("display_data", "execute_result"):
                out.get("metadata", {}).pop("transient", None)
            kept.append(out)
        cell.outputs = kept


_ADDRESS = re.compile(r"\bat 0x[0-9a-fA-F]{6,16}\b")


def output_warnings(nb) -> list[str]:
    """Outputs that would change from run to run: memory addresses in text."""
    found = []
    for i, cell in enumerate(nb.cells):
        for out in cell.get("outputs", []):
            text = out.get("text", "") + out.get("data", {}).get("text/plain", "")
            if _ADDRESS.search(text):
                found.append(
                    f"cell {i} prints a memory address ({_ADDRESS.search(text).group(0)}): end the line "
                    "with ';' or assign the result (fig = ..., _ = ax.plot(...))"
                )
                break
    return found


def build(src: Path, execute: bool = True, quiet: bool = False) -> Path:
    """Build one notebook from its source; returns the notebook's path."""
    import nbformat

    src = Path(src).resolve()
    out = notebook_path(src)
    cells = parse_percent(src.read_text(encoding="utf-8"), where=_show(src))
    nb = make_notebook(cells)
    t0 = time.monotonic()
    if execute:
        from nbclient import NotebookClient
        from nbclient.exceptions import CellExecutionError

        # The inline backend stores figures as PNG; a backend forced from outside would not.
        os.environ.pop("MPLBACKEND", None)
        client = NotebookClient(
            nb,
            kernel_name=KERNEL_NAME,
            timeout=CELL_TIMEOUT_S,
            resources={"metadata": {"path": str(out.parent)}},
            record_timing=False,
            store_widget_state=True,  # False breaks Output widgets in nbclient 0.10-0.11; the state is dropped below
            coalesce_streams=True,
            allow_errors=False,
        )
        try:
            _execute(client, nb, src.name)
        except CellExecutionError as exc:
            raise BuildError(f"{src.name}: a cell failed, the notebook was not written:\n{exc}") from None
    _stabilise(nb)
    for warning in output_warnings(nb):
        print(f"warning: {src.name}: {warning}", file=sys.stderr)
    text = nbformat.writes(nb) + "\n"
    tmp = out.with_name(f".{out.name}.tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, out)
    if not quiet:
        print(
            f"{_show(out)}: {len(nb.cells)} cells, "
            f"{'executed in %.1f s' % (time.monotonic() - t0) if execute else 'not executed'}"
        )
    return out


def _execute(client, nb, name: str) -> None:
    """Run the code cells in order, rendering each markdown cell's fields when the run reaches it."""
    client.reset_execution_trackers()
    with client.setup_kernel():
        read_in_steps(client.kc.shell_channel)
        for index, cell in enumerate(nb.cells):
            if cell.cell_type == "markdown":
                _render_cell(client, nb, cell, index, name)
            else:
                client.execute_cell(cell, index, execution_count=client.code_cells_executed + 1)
        client.set_widgets_metadata()


def read_in_steps(channel, step_s: float = SHELL_STEP_S) -> None:
    """Make ``channel.get_msg`` wait in steps of at most ``step_s`` seconds, to the same overall timeout.

    A single long wait for a cell's reply on the shell channel can now and then miss a reply that has
    arrived, after a cell that shows an ipywidgets ``Output`` (jupyter/nbclient#312): the build then sat
    idle until the cell's timeout. Each fresh wait sees what has arrived, so a missed wake-up costs at most
    one step.
    """
    from queue import Empty

    read = channel.get_msg

    async def get_msg(timeout: float | None = None):
        end = None if timeout is None else time.monotonic() + timeout
        while True:
            left = step_s if end is None else max(0.0, end - time.monotonic())
            try:
                msg = read(timeout=min(step_s, left))
                return await msg if hasattr(msg, "__await__") else msg
            except Empty:
                if end is not None and time.monotonic() >= end:
                    raise

    channel.get_msg = get_msg


def _render_cell(client, nb, cell, index: int, name: str) -> None:
    """Replace a markdown cell's ``{{ expr }}`` fields by their values in the running kernel."""
    import json

    import nbformat
    from nbclient.exceptions import CellExecutionError

    fields = prose_fields(cell.source)
    if not fields:
        return
    probe = nbformat.v4.new_code_cell(_field_code(fields))
    try:
        client.execute_cell(probe, index, store_history=False)
    except CellExecutionError as exc:
        raise BuildError(
            f"{name}: markdown cell {index}: a field could not be computed from the cells above it "
            f"({', '.join(e for e, _ in fields)}):\n{exc}"
        ) from None
    finally:
        # nbclient files the probe in the markdown cell's place and counts it as a code cell: undo both.
        nb.cells[index] = cell
        client.code_cells_executed -= 1
    text = "".join(o.get("text", "") for o in probe.outputs if o.get("output_type") == "stream")
    values = json.loads(text.strip().splitlines()[-1])
    cell.metadata[TEMPLATE_KEY] = {"template": cell.source}
    cell.source = render_prose(cell.source, values)


def source_of(cell) -> str:
    """A built cell's source as written in the percent script (a rendered markdown cell's template)."""
    if cell.cell_type == "markdown":
        return cell.get("metadata", {}).get(TEMPLATE_KEY, {}).get("template", cell.source)
    return cell.source


# -- checking --------------------------------------------------------------------------
def _show(path: Path) -> str:
    """A path as the user would type it: relative to the repository when inside it."""
    path = Path(path).resolve()
    return str(path.relative_to(REPO)) if path.is_relative_to(REPO) else str(path)


def check_one(src: Path) -> list[str]:
    """Problems with one source's notebook (empty when it is up to date)."""
    import nbformat

    src = Path(src)
    out = notebook_path(src)
    name = _show(out)
    if not out.exists():
        return [f"{name}: missing; build it with: python tools/nbbuild.py {_show(src)}"]
    want = parse_percent(src.read_text(encoding="utf-8"), where=_show(src))
    nb = nbformat.read(str(out), as_version=4)
    have = [Cell(c.cell_type, source_of(c)) for c in nb.cells]
    problems = []
    if have != want:
        first = next((i for i, (a, b) in enumerate(zip(have, want)) if a != b), min(len(have), len(want)))
        problems.append(
            f"{name}: cells differ from {src.name} (first difference at cell {first}; "
            f"{len(have)} cells in the notebook, {len(want)} in the source); "
            f"rebuild: python tools/nbbuild.py {_show(src)}"
        )
        return problems
    for i, c in enumerate(nb.cells):
        if c.cell_type != "code":
            continue
        if c.source.strip() and c.get("execution_count") is None:
            problems.append(f"{name}: cell {i} was never executed; rebuild: python tools/nbbuild.py {_show(src)}")
            break
        if any(o.get("output_type") == "error" for o in c.get("outputs", [])):
            problems.append(f"{name}: cell {i} stores an error; fix the source and rebuild")
            break
    return problems


def check(sources: list[Path] | None = None) -> list[str]:
    """Problems with every notebook built from a source, and numbered notebooks without one."""
    sources = all_sources() if sources is None else [Path(s) for s in sources]
    problems: list[str] = []
    for src in sources:
        problems += check_one(src)
    built = {notebook_path(s).resolve() for s in all_sources()}
    for nb in sorted(NOTEBOOKS.glob("[0-9][0-9]_*.ipynb")):
        if nb.resolve() not in built:
            problems.append(
                f"{nb.relative_to(REPO)}: no source notebooks/src/{nb.stem}.py; notebooks are built from sources"
            )
    return problems


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="nbbuild", description="Build course notebooks from notebooks/src/*.py and check them."
    )
    p.add_argument("sources", nargs="*", type=Path, help="percent scripts to build (notebooks/src/NN_topic.py)")
    p.add_argument("--all", action="store_true", help="build every source under notebooks/")
    p.add_argument("--check", action="store_true", help="only check that the notebooks match their sources")
    p.add_argument("--no-execute", action="store_true", help="write the notebook without running it (drafts only)")
    args = p.parse_args(argv)
    try:
        if args.check:
            problems = check(args.sources or None)
            for line in problems:
                print(line, file=sys.stderr)
            if not problems:
                print(f"{len(args.sources or all_sources())} notebooks match their sources")
            return 1 if problems else 0
        sources = all_sources() if args.all else args.sources
        if not sources:
            p.error("give a source (notebooks/src/NN_topic.py) or --all")
        for src in sources:
            build(src, execute=not args.no_execute)
    except BuildError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
