"""The browser tests run only when asked for by path: ``pytest tests/browser`` (``make test-browser``).

They start JupyterLab and a headless Chromium, which takes a minute on a small machine, so
``pytest tests`` and ``make test`` (unit tests and notebooks) leave them out.
"""

from __future__ import annotations

from pathlib import Path

HERE = Path(__file__).resolve().parent


def _asked_for(config) -> bool:
    for arg in config.args:
        path = Path(str(arg).split("::")[0]).resolve()
        if path == HERE or HERE in path.parents:
            return True
    return False


def pytest_ignore_collect(collection_path, config):
    if collection_path.resolve().parent == HERE and collection_path.name.startswith("test_"):
        return not _asked_for(config)
    return None
