"""The docs pages' Python code blocks run as written, and every page is in the site's nav.

``mkdocs build --strict`` (CI, after the tests) checks the rest: links, includes, API targets.
The worked example the custom-task page includes is tested in tests/envs/test_flip_example.py.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PAGES = sorted(DOCS.rglob("*.md"))
# (page, block) for every ```python block but the includes (``--8<--`` lines, the example).
BLOCKS = [
    (page.relative_to(DOCS).as_posix(), block)
    for page in PAGES
    for block in re.findall(r"```python\n(.*?)```", page.read_text(), flags=re.S)
    if "--8<--" not in block
]


def test_the_docs_have_python_blocks():
    # Guards the extraction: a changed fence style would otherwise test nothing.
    assert {page for page, _ in BLOCKS} >= {"simulator.md", "environments.md", "custom-task.md"}


@pytest.mark.parametrize(
    ("page", "block"), BLOCKS, ids=[f"{p}-{i}" for i, (p, _) in enumerate(BLOCKS)]
)
def test_docs_block_runs(page, block):
    # A fresh interpreter per block, from the repository's root (the custom-task page's block
    # imports docs/examples/flip_task.py by that path).
    result = subprocess.run(
        [sys.executable, "-c", block],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "PYTHONPATH": str(ROOT), "SDL_VIDEODRIVER": "dummy"},
    )
    assert result.returncode == 0, f"{page}:\n{block}\n{result.stderr}"


def _nav_pages(node) -> list[str]:
    if isinstance(node, str):
        return [node]
    if isinstance(node, dict):
        return [p for value in node.values() for p in _nav_pages(value)]
    return [p for item in node for p in _nav_pages(item)]


def test_every_page_is_in_the_nav():
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text())
    nav = set(_nav_pages(config["nav"]))
    assert nav == {page.relative_to(DOCS).as_posix() for page in PAGES}
