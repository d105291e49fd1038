"""The annotations hold: mypy over ``simpro_mj`` and ``controllers`` finds no error.

The checker runs in this process with the settings of ``[tool.mypy]`` in
pyproject.toml (the files, the checks, the third-party packages read as ``Any``)
and its cache in ``.mypy_cache``: about 20 s of CPU on a fresh clone, under a
second once the cache holds the unchanged modules. It runs first
(``tests/conftest.py``: ``WHILE_THE_STEP_COMPILES``), beside the step's compile on a
fresh clone, rather than ending the run alone.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from mypy import api

ROOT = Path(__file__).resolve().parents[1]


def test_mypy_finds_no_error(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(ROOT)  # [tool.mypy]'s files and cache_dir are relative to the root
    out, err, status = api.run(["--config-file", str(ROOT / "pyproject.toml")])
    assert status == 0, out + err
    # every module of both packages was read (the settings name the right folders)
    modules = sum(1 for pkg in ("simpro_mj", "controllers") for _ in (ROOT / pkg).rglob("*.py"))
    assert out.strip() == f"Success: no issues found in {modules} source files", out
