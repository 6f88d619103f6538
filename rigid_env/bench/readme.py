"""``python -m rigid_env.bench.readme [--check]``: the README's result tables, from JSON.

The README's measured tables are not typed by hand: each sits between two markers,

    <!-- results: NAME -->
    ...generated...
    <!-- end results -->

and NAME picks a renderer below over a JSON file in ``docs/results/`` that a command wrote
(``python -m rigid_env.bench all --out docs/results``, or a copy of the main job's
``main_job.json``). ``--check`` rewrites nothing and exits 1 when the README differs from what
the JSON gives (a test runs it, so a table cannot go stale against its JSON).

A JSON file that carries ``rows`` and ``columns`` (``[header, key, format]`` triples, Python
format specs) renders generically; the bench's files render through their modules' tables.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "docs" / "results"
BLOCK = re.compile(r"(<!-- results: (\S+) -->\n)(.*?)(<!-- end results -->)", re.S)


def rows_table(doc: dict) -> str:
    """A markdown table from a self-describing JSON document (``rows`` and ``columns``)."""
    columns = doc["columns"]
    lines = [
        "| " + " | ".join(h for h, _, _ in columns) + " |",
        "|" + "|".join("---" for _ in columns) + "|",
    ]
    for row in doc["rows"]:
        cells = []
        for _, key, spec in columns:
            value = row.get(key)
            cells.append("—" if value is None else format(value, spec))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _bench(command: str, part: str) -> Callable[[dict], str]:
    def render(doc: dict) -> str:
        import importlib

        module = importlib.import_module(f"rigid_env.bench.{command}")
        return getattr(module, part)(doc)

    return render


# NAME -> (JSON file in docs/results, renderer)
RENDERERS: dict[str, tuple[str, Callable[[dict], str]]] = {
    "accuracy": ("accuracy.json", _bench("accuracy", "summary")),
    "stability": ("stability.json", _bench("stability", "summary")),
    "speed": ("speed.json", _bench("speed", "summary")),
    "eval-reorient": ("eval-reorient.json", rows_table),
    "eval-box-landing": ("eval-box-landing.json", rows_table),
    "sweep-reorient": ("sweep-reorient.json", rows_table),
}


def render(text: str, results: Path = RESULTS) -> str:
    """``text`` with every marked block regenerated from its JSON."""

    def block(match: re.Match) -> str:
        name = match.group(2)
        if name not in RENDERERS:
            raise ValueError(f"README: unknown results block {name!r}; known: {sorted(RENDERERS)}")
        file, renderer = RENDERERS[name]
        doc = json.loads((results / file).read_text())
        return match.group(1) + renderer(doc).strip() + "\n" + match.group(4)

    return BLOCK.sub(block, text)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m rigid_env.bench.readme", description=__doc__)
    parser.add_argument("--readme", type=Path, default=ROOT / "README.md")
    parser.add_argument("--results", type=Path, default=RESULTS)
    parser.add_argument("--check", action="store_true", help="exit 1 if the README is stale")
    args = parser.parse_args(argv)
    text = args.readme.read_text()
    new = render(text, args.results)
    if args.check:
        if new != text:
            print(f"{args.readme}: generated tables differ from {args.results}; rerun without --check")
            return 1
        return 0
    if new != text:
        from rigid_env.files import write_text

        write_text(args.readme, new)
        print(f"rewrote the generated tables of {args.readme}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
