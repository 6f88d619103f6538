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
    # `python -m rigid_env.bench.readme` rewrites the marked tables from docs/results/*.json;
    # --check fails when the README differs from what the JSON gives.
    result = subprocess.run(
        [sys.executable, "-m", "rigid_env.bench.readme", "--check"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stdout + result.stderr
