"""Every course notebook is built from its source in notebooks/src and is up to date with it."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

from fidlearn.data import repo_dir

_spec = importlib.util.spec_from_file_location("nbbuild", repo_dir() / "tools" / "nbbuild.py")
nbbuild = importlib.util.module_from_spec(_spec)
sys.modules.setdefault("nbbuild", nbbuild)
_spec.loader.exec_module(nbbuild)


def test_every_notebook_matches_its_source():
    problems = nbbuild.check()
    assert not problems, "\n".join(problems)


def test_numbered_notebooks_have_sources():
    sources = {p.stem for p in (repo_dir() / "notebooks" / "src").glob("[0-9][0-9]_*.py")}
    notebooks = {p.stem for p in (repo_dir() / "notebooks").glob("[0-9][0-9]_*.ipynb")}
    assert notebooks <= sources, f"notebooks without a source: {sorted(notebooks - sources)}"


def test_parse_percent_splits_code_and_markdown_cells():
    text = (
        "# a note before the first cell is ignored\n"
        "# %% [markdown]\n"
        "# # Title\n"
        "#\n"
        "# Some *text*.\n"
        "\n"
        "# %%\n"
        "# %matplotlib inline\n"
        "x = 1  # a comment stays\n"
        "\n"
        "# %%\n"
        "# NBVAL_IGNORE_OUTPUT\n"
        "print(x)\n"
    )
    cells = nbbuild.parse_percent(text)
    assert cells == [
        nbbuild.Cell("markdown", "# Title\n\nSome *text*."),
        nbbuild.Cell("code", "%matplotlib inline\nx = 1  # a comment stays"),
        nbbuild.Cell("code", "# NBVAL_IGNORE_OUTPUT\nprint(x)"),
    ]


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("x = 1\n# %%\ny = 2\n", "code before the first"),
        ("# %% [markdown]\nnot a comment\n", "must start with '# '"),
        ("# %% [raw]\n# x\n", "unknown cell marker"),
        ("\n\n", "no cells"),
    ],
)
def test_parse_percent_says_what_is_wrong(text, message):
    with pytest.raises(nbbuild.BuildError, match=message):
        nbbuild.parse_percent(text, where="demo.py")


def test_check_reports_a_stale_notebook(tmp_path: Path):
    import nbformat

    src = tmp_path / "src" / "01_demo.py"
    src.parent.mkdir()
    src.write_text("# %%\nx = 1\n")
    assert "missing" in nbbuild.check_one(src)[0]
    nb = nbbuild.make_notebook(nbbuild.parse_percent(src.read_text()))
    nb.cells[0].execution_count = 1
    nbformat.write(nb, str(tmp_path / "01_demo.ipynb"))
    assert nbbuild.check_one(src) == []
    src.write_text("# %%\nx = 2\n")
    (problem,) = nbbuild.check_one(src)
    assert "cells differ" in problem
    assert "nbbuild.py" in problem
    nb.cells[0].source = "x = 2"
    nb.cells[0].execution_count = None
    nbformat.write(nb, str(tmp_path / "01_demo.ipynb"))
    assert "never executed" in nbbuild.check_one(src)[0]


def test_notebook_path_follows_the_src_folder():
    assert nbbuild.notebook_path(Path("notebooks/src/03_x.py")) == Path("notebooks/03_x.ipynb")
    assert nbbuild.notebook_path(Path("notebooks/exercises/src/03_x.py")) == Path("notebooks/exercises/03_x.ipynb")
    with pytest.raises(nbbuild.BuildError, match="src"):
        nbbuild.notebook_path(Path("notebooks/03_x.py"))


def test_build_executes_and_leaves_out_what_varies(tmp_path: Path):
    """One real build: outputs stored, widget model ids, timestamps and random cell ids left out."""
    import nbformat

    src = tmp_path / "src" / "01_demo.py"
    src.parent.mkdir()
    src.write_text(
        "# %% [markdown]\n# # Demo\n\n"
        "# %%\nimport os\nprint(os.path.basename(os.getcwd()), 6 * 7)\n\n"
        "# %%\n# NBVAL_IGNORE_OUTPUT\nimport ipywidgets as W\nout = W.Output()\nwith out:\n    print('inside')\n"
        "W.VBox([W.IntSlider(3), out])\n"
    )
    out = nbbuild.build(src, quiet=True)
    nb = nbformat.read(str(out), as_version=4)
    assert [c.id for c in nb.cells] == ["cell-000", "cell-001", "cell-002"]
    assert nb.cells[1].outputs[0].text == f"{tmp_path.name} 42\n"  # run in the notebook's folder
    widget_out = nb.cells[2].outputs[0]
    assert "text/plain" in widget_out.data
    assert nbbuild._WIDGET_MIME not in widget_out.data
    assert "widgets" not in nb.metadata
    assert all("execution" not in c.metadata for c in nb.cells)
    assert nbbuild.check_one(src) == []


class _MissesItsFirstWakeUp:
    """A shell channel whose first wait sleeps its whole timeout though the reply has arrived (nbclient#312)."""

    def __init__(self, reply_after_s: float | None = 0.0):
        self.waits: list[float | None] = []
        self.ready_at = reply_after_s

    async def get_msg(self, timeout=None):
        import asyncio
        import time
        from queue import Empty

        self.waits.append(timeout)
        if len(self.waits) == 1:
            self.t0 = time.monotonic()
            await asyncio.sleep(timeout if timeout is not None else 3600)
            raise Empty
        if self.ready_at is not None and time.monotonic() - self.t0 >= self.ready_at:
            return {"msg_type": "execute_reply"}
        await asyncio.sleep(timeout)
        raise Empty


def test_a_missed_wake_up_on_the_shell_channel_costs_one_step_not_the_cell_timeout():
    import asyncio
    import time

    channel = _MissesItsFirstWakeUp()
    nbbuild.read_in_steps(channel, step_s=0.05)
    t0 = time.monotonic()
    msg = asyncio.run(asyncio.wait_for(channel.get_msg(timeout=600), 5))
    assert msg == {"msg_type": "execute_reply"}
    assert time.monotonic() - t0 < 1.0
    assert all(w <= 0.05 for w in channel.waits)


def test_the_shell_channel_still_times_out_at_the_cells_timeout():
    import asyncio
    import time
    from queue import Empty

    channel = _MissesItsFirstWakeUp(reply_after_s=None)
    nbbuild.read_in_steps(channel, step_s=0.05)
    t0 = time.monotonic()
    with pytest.raises(Empty):
        asyncio.run(channel.get_msg(timeout=0.3))
    assert 0.29 <= time.monotonic() - t0 < 1.0
    assert len(channel.waits) >= 6


@pytest.mark.parametrize(
    ("markdown", "fields"),
    [
        ("no fields here {not one}", []),
        ("ratio {{ ratio:.2f }} of {{n}}", [("ratio", ".2f"), ("n", "")]),
        ("a slice {{ x[1:3] }}", [("x[1:3]", "")]),
        ("a share {{ hits / total:.1% }}", [("hits / total", ".1%")]),
        ("a dict {{ {'a': 1}['a'] }}", [("{'a': 1}['a']", "")]),
    ],
)
def test_prose_fields_are_found_with_their_format(markdown, fields):
    assert nbbuild.prose_fields(markdown) == fields


def test_prose_numbers_come_from_the_cells_above(tmp_path: Path):
    """A number cited in a markdown cell is the value the code above it computed, not what the code computes later."""
    import nbformat

    src = tmp_path / "src" / "01_demo.py"
    src.parent.mkdir()
    src.write_text(
        "# %%\nratio = 1.3912\nprint(ratio)\n\n"
        "# %% [markdown]\n# The median ratio is {{ ratio:.2f }} ({{ ratio:.0% }}).\n\n"
        "# %%\nratio = 5\nprint(ratio)\n"
    )
    nbbuild.build(src, quiet=True)
    nb = nbformat.read(str(tmp_path / "01_demo.ipynb"), as_version=4)
    assert nb.cells[1].source == "The median ratio is 1.39 (139%)."
    assert [c.execution_count for c in nb.cells if c.cell_type == "code"] == [1, 2]
    assert nbbuild.check_one(src) == []  # the template, not the rendered text, is compared with the source
    src.write_text(src.read_text().replace("{{ ratio:.2f }}", "{{ ratio:.3f }}"))
    assert "cells differ" in nbbuild.check_one(src)[0]


def test_a_field_that_cannot_be_computed_stops_the_build(tmp_path: Path):
    src = tmp_path / "src" / "01_demo.py"
    src.parent.mkdir()
    src.write_text("# %%\nx = 1\n\n# %% [markdown]\n# We saw {{ y }}.\n")
    with pytest.raises(nbbuild.BuildError, match="markdown cell 1"):
        nbbuild.build(src, quiet=True)
    assert not (tmp_path / "01_demo.ipynb").exists()
