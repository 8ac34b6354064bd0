"""Draw fidlearn's package map from its imports: which part of the package uses which.

python tools/package_map.py            # print the map (Markdown with a Mermaid graph)
python tools/package_map.py --write    # write it into CONTRIBUTING.md between its markers
python tools/package_map.py --check    # exit 1 if CONTRIBUTING.md's map is not the current one

Every module's source is read with :mod:`ast` (nothing is imported) and every ``import`` is
followed, also those inside functions: a lazy import still ties two modules together. Modules are
gathered into the package's parts (``fidlearn/pose/`` is ``pose``, ``fidlearn/_lens.py`` is
``_lens``); the map shows each part's direct uses with the ones already implied by a longer path
left out (the transitive reduction), in layers from the bottom (parts that use no other part) up.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "fidlearn"
CONTRIBUTING = ROOT / "CONTRIBUTING.md"
START = "<!-- package map: drawn by tools/package_map.py from the imports; do not edit by hand -->"
END = "<!-- end of package map -->"


def modules(package: Path = PACKAGE) -> dict[str, Path]:
    """Every module of the package by dotted name (a package by its own name, for its ``__init__.py``)."""
    found = {}
    for path in sorted(package.rglob("*.py")):
        parts = (package.name,) + path.relative_to(package).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        found[".".join(parts)] = path
    return found


def imported(name: str, path: Path, known: dict[str, Path]) -> set[str]:
    """The package's modules that module ``name`` (at ``path``) imports, lazily or not.

    Importing ``a.b.c`` runs the packages ``a.b`` on the way too, so they count, except the
    top package and the importer's own packages.
    """
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    wanted = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            wanted.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(base + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            for alias in node.names:  # a submodule by its own name, any other name from the module
                sub = f"{base}.{alias.name}"
                wanted.add(sub if sub in known else base)
    out = set()
    for target in wanted & known.keys():
        out.add(target)
        parts = target.split(".")
        for i in range(2, len(parts)):
            parent = ".".join(parts[:i])
            if not (name == parent or name.startswith(parent + ".")):
                out.add(parent)
    out.discard(name)
    return out


def module_graph(package: Path = PACKAGE) -> dict[str, set[str]]:
    """Each module of the package and the package's modules it imports."""
    known = modules(package)
    return {name: imported(name, path, known) for name, path in known.items()}


def part_of(module: str) -> str:
    """The part of the package a module belongs to: its first name below the top package."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else parts[0]


def part_graph(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    """The module graph gathered into parts, without a part's uses of itself or of the top package."""
    top = next(iter(graph)).split(".")[0]
    parts: dict[str, set[str]] = {}
    for module, targets in graph.items():
        if module == top or module.endswith(".__main__"):  # entry points stand above every part
            continue
        uses = parts.setdefault(part_of(module), set())
        uses.update(part_of(t) for t in targets if t != top)
    for name, uses in parts.items():
        uses.discard(name)
    return parts


def layers(parts: dict[str, set[str]]) -> list[list[str]]:
    """Parts by height: 0 uses no other part, n uses one of height n-1 at most (a circle is an error)."""
    height: dict[str, int] = {}
    visiting: set[str] = set()

    def measure(part: str) -> int:
        if part in height:
            return height[part]
        if part in visiting:
            raise ValueError(f"the parts use each other in a circle through {part!r}")
        visiting.add(part)
        height[part] = 1 + max((measure(u) for u in parts[part]), default=-1)
        visiting.discard(part)
        return height[part]

    for part in parts:
        measure(part)
    out: list[list[str]] = [[] for _ in range(max(height.values(), default=-1) + 1)]
    for part in sorted(parts):
        out[height[part]].append(part)
    return out


def reduced(parts: dict[str, set[str]]) -> dict[str, set[str]]:
    """Each part's direct uses that no longer path through another use already implies."""

    def reach(part: str, seen: set[str]) -> set[str]:
        for use in parts[part]:
            if use not in seen:
                seen.add(use)
                reach(use, seen)
        return seen

    below = {part: reach(part, set()) for part in parts}
    return {part: {u for u in uses if not any(u in below[v] for v in uses if v != u)} for part, uses in parts.items()}


def draw(package: Path = PACKAGE) -> str:
    """The map as Markdown: a Mermaid graph (bottom up) and the layers in words."""
    parts = part_graph(module_graph(package))
    levels = layers(parts)
    edges = reduced(parts)
    lines = [START, "", "```mermaid", "flowchart BT"]
    lines += [f'    p_{part}["{part}"]' for part in sorted(parts)]
    lines += [f"    p_{part} --> p_{use}" for part in sorted(parts) for use in sorted(edges[part])]
    lines += ["```", "", "| layer | parts (each uses only parts in lower layers) |", "| --- | --- |"]
    for i, level in enumerate(levels):
        lines.append(f"| {i} | {', '.join(f'`{p}`' for p in level)} |")
    lines += ["", END]
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    """Print, write or check the map (see the module's docstring)."""
    text = draw()
    if not argv:
        print(text)
        return 0
    current = CONTRIBUTING.read_text(encoding="utf-8")
    if START not in current or END not in current:
        print(f"{CONTRIBUTING} has no package map markers", file=sys.stderr)
        return 1
    head, rest = current.split(START, 1)
    tail = rest.split(END, 1)[1]
    wanted = head + text + tail
    if argv == ["--check"]:
        if wanted != current:
            print(
                "CONTRIBUTING.md's package map is out of date: run python tools/package_map.py --write", file=sys.stderr
            )
            return 1
        return 0
    if argv == ["--write"]:
        CONTRIBUTING.write_text(wanted, encoding="utf-8")
        return 0
    print(__doc__, file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
