"""Print pip constraints that pin every direct dependency of fidlearn to its declared lower bound.

    python tools/floor_constraints.py > floors.txt
    pip install -c floors.txt -e ".[test]"

``make test-floor`` does this in ``.venv-floor``, so CI proves that the floors in
``pyproject.toml`` are true: the whole suite passes on the oldest versions a user may have.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    tomllib = None

ROOT = Path(__file__).resolve().parent.parent


def _requirements(text: str) -> list[str]:
    if tomllib is not None:
        project = tomllib.loads(text)["project"]
        return list(project["dependencies"]) + list(project["optional-dependencies"]["test"])
    reqs = []
    for block in (
        re.search(r"^dependencies\s*=\s*\[(.*?)\]", text, re.S | re.M).group(1),
        re.search(r"^test\s*=\s*\[(.*?)\]", text, re.S | re.M).group(1),
    ):
        reqs += re.findall(r'"([^"]+)"', re.sub(r"#.*", "", block))
    return reqs


def floors(pyproject: Path = ROOT / "pyproject.toml") -> list[str]:
    """``name==lowest`` for every direct dependency (runtime and test) with a ``>=`` bound."""
    out = []
    for req in _requirements(pyproject.read_text(encoding="utf-8")):
        m = re.match(r"^\s*([A-Za-z0-9_.\-]+)\s*(\[[^\]]*\])?\s*(.*)$", req)
        name, spec = m.group(1), m.group(3)
        low = re.search(r">=\s*([0-9][0-9A-Za-z.\-]*)", spec)
        if low:
            out.append(f"{name}=={low.group(1)}")
    return out


if __name__ == "__main__":
    print("\n".join(floors()))
    sys.exit(0)
