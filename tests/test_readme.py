"""The README's Python code blocks run as written, and its generated tables are up to date."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()
BLOCKS = re.findall(r"```python\n(.*?)```", README, flags=re.S)


def test_readme_has_python_blocks():
    # Guards the extraction itself: a changed fence style would otherwise test nothing.
    assert len(BLOCKS) >= 3


@pytest.mark.parametrize("index", range(len(BLOCKS)))
def test_readme_block_runs(index, tmp_path):
    # A fresh interpreter per block, in an empty folder: a block may use only what it imports.
    result = subprocess.run(
        [sys.executable, "-c", BLOCKS[index]],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
        env={
            **os.environ,
            "PYTHONPATH": str(ROOT),
            "SDL_VIDEODRIVER": "dummy",
            "MPLBACKEND": "Agg",
        },
    )
    assert result.returncode == 0, f"block {index} failed:\n{BLOCKS[index]}\n{result.stderr}"


def test_generated_tables_match_their_json():
    # `python -m rigid_env.bench.readme` rewrites the marked tables of the README and the docs'
    # results page from docs/results/*.json; --check fails when a page differs from what the
    # JSON gives.
    result = subprocess.run(
        [sys.executable, "-m", "rigid_env.bench.readme", "--check"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stdout + result.stderr


def test_the_pages_hold_their_generated_tables():
    # --check passes trivially on a page whose markers were lost: each page must keep its blocks.
    from rigid_env.bench.readme import BLOCK, PAGES, RENDERERS

    found = {page.name: {m.group(2) for m in BLOCK.finditer(page.read_text())} for page in PAGES}
    assert found["results.md"] == set(RENDERERS) - {"speed-targets", "compile"}
    assert {"main-job", "speed-targets", "compile"} <= found["README.md"]


def test_check_fails_on_a_stale_table(tmp_path):
    page = tmp_path / "page.md"
    page.write_text("<!-- results: main-job -->\n| stale |\n<!-- end results -->\n")
    run = [sys.executable, "-m", "rigid_env.bench.readme", str(page)]
    check = subprocess.run([*run, "--check"], cwd=ROOT, capture_output=True, text=True)
    assert check.returncode == 1 and "differ" in check.stdout
    assert subprocess.run(run, cwd=ROOT, capture_output=True).returncode == 0
    assert "RigidEnv/BoxLanding-v0" in page.read_text()
    assert subprocess.run([*run, "--check"], cwd=ROOT).returncode == 0
