"""Every public function, class and method of fidlearn documents itself in numpydoc sections.

A learner reads ``help(fidlearn.locate)`` before the source: each public callable says what every
parameter is (shape, frame and unit for arrays) in a ``Parameters`` section and what comes back in
``Returns`` (or ``Yields``); a class documents its fields in ``Parameters`` or ``Attributes``.
Public means: defined in a module of the ``fidlearn`` package whose dotted path has no part that
starts with ``_``, with a name that does not start with ``_``. The examples in these docstrings
run as doctests (``pytest --doctest-modules fidlearn``, part of ``make test``).
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import re

import pytest

import fidlearn

SKIP_MODULES = {"fidlearn.__main__"}


def _public_modules():
    names = ["fidlearn"]
    for info in pkgutil.walk_packages(fidlearn.__path__, "fidlearn."):
        if not any(part.startswith("_") for part in info.name.split(".")[1:]) and info.name not in SKIP_MODULES:
            names.append(info.name)
    return [importlib.import_module(n) for n in sorted(names)]


def _section(doc: str, *names: str) -> bool:
    return any(re.search(rf"^\s*{name}\n\s*-{{{len(name)}}}\s*$", doc, re.MULTILINE) for name in names)


def _takes_arguments(fn) -> bool:
    try:
        params = inspect.signature(fn).parameters
    except (TypeError, ValueError):
        return False
    return any(p not in ("self", "cls") for p in params)


def _returns_something(fn) -> bool:
    src_ann = inspect.signature(fn).return_annotation
    return src_ann not in (None, "None", inspect.Signature.empty) or inspect.isgeneratorfunction(fn)


def _problems(qualname: str, obj) -> list[str]:
    doc = inspect.getdoc(obj) or ""
    if not doc:
        return [f"{qualname}: no docstring"]
    out = []
    if inspect.isclass(obj):
        if _takes_arguments(obj) and not _section(doc, "Parameters", "Attributes"):
            out.append(f"{qualname}: no Parameters or Attributes section")
        return out
    if _takes_arguments(obj) and not _section(doc, "Parameters"):
        out.append(f"{qualname}: no Parameters section")
    if _returns_something(obj) and not _section(doc, "Returns", "Yields"):
        out.append(f"{qualname}: no Returns section")
    return out


def _public_callables():
    seen = set()
    for module in _public_modules():
        for name, obj in vars(module).items():
            if name.startswith("_") or getattr(obj, "__module__", None) != module.__name__:
                continue
            if not (inspect.isfunction(obj) or inspect.isclass(obj)) or id(obj) in seen:
                continue
            seen.add(id(obj))
            yield f"{module.__name__}.{name}", obj
            if inspect.isclass(obj) and not issubclass(obj, BaseException):
                for attr, member in vars(obj).items():
                    if attr.startswith("_") or not inspect.isfunction(member):
                        continue
                    yield f"{module.__name__}.{name}.{attr}", member


CALLABLES = dict(_public_callables())


def test_the_walk_finds_the_pipeline():
    for name in ("fidlearn.camera.Camera", "fidlearn.frames.invert_transform", "fidlearn.markermap.MarkerMap"):
        assert name in CALLABLES


def test_section_detection():
    assert _section("Do.\n\nParameters\n----------\nx : int\n", "Parameters")
    assert not _section("Do.\n\nParameters: x\n", "Parameters")


@pytest.mark.parametrize("qualname", sorted(CALLABLES))
def test_public_callable_has_numpydoc_sections(qualname):
    problems = _problems(qualname, CALLABLES[qualname])
    assert not problems, "; ".join(problems)
