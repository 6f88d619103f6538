"""``python -m rigid_env.bench.readme [--check] [FILE ...]``: the result tables, from JSON.

The measured tables of the README (a few headline rows) and of the docs' results page
(``docs/results.md``, every table) are not typed by hand: each sits between two markers,

    <!-- results: NAME -->
    ...generated...
    <!-- end results -->

and NAME picks a renderer below over a JSON file in ``docs/results/`` that a command wrote
(``python -m rigid_env.bench all --out docs/results``, or a copy of the main job's
``main_job.json``). ``--check`` rewrites nothing and exits 1 when a page differs from what the
JSON gives (a test runs it, so a table cannot go stale against its JSON).

A JSON file that carries ``rows`` and ``columns`` (``[header, key, format]`` triples, Python
format specs) renders generically; the bench's files render through their modules' tables.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from .. import cli

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "docs" / "results"
PAGES = (ROOT / "README.md", ROOT / "docs" / "results.md")  # the files with generated tables
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


def accuracy_summary(doc: dict) -> str:
    """Observed orders and the cheapest way to each error target (the full report prints all)."""
    from . import accuracy

    return "\n".join(
        [
            "Observed order (slope of log error against log dt in the asymptotic range):",
            "",
            accuracy.orders_table(doc),
            "",
            "Cheapest measured integrator and dt reaching each orientation error on the "
            f"Dzhanibekov flip after {doc['duration_s']:g} s:",
            "",
            accuracy.targets_table(doc),
        ]
    )


def stability_summary(doc: dict) -> str:
    from . import stability

    return stability.table(doc)


def speed_summary(doc: dict) -> str:
    """Body-steps per second, the targets, and the environments' step rates."""
    from . import speed

    first = speed.table(doc).split("\n\nStage breakdown")[0]
    return "\n".join(
        [
            first,
            "",
            *speed.targets(doc),
            "",
            "Environment steps per second:",
            "",
            speed.env_table(doc),
        ]
    )


def speed_targets(doc: dict) -> str:
    """The speed targets alone (the README's headline of the speed run)."""
    from . import speed

    return "\n".join(speed.targets(doc))


def compile_summary(doc: dict) -> str:
    """One sentence from the speed run's compile probe: a scene's first step in a fresh process,
    cold (empty caches: it compiles) and cached, for the free body and the landing scene."""
    from . import speed

    runs = {(r["case"], r["run"]): r["first_step_s"] for r in doc["compile"]}

    def both(case: str) -> str:
        return f"{runs[(case, 'cold')]:.1f} s ({runs[(case, 'cached')]:.1f} s cached)"

    spring = runs.get(("landing_spring", "cached"))
    reuse = (
        ""
        if spring is None
        else f"; the same box with a spring and damping added, after it: {spring:.1f} s"
    )
    wall = {(r["case"], r["run"]): r["process_s"] for r in doc["compile"]}
    together = wall.get(("landing", "together"))
    crowd = (
        ""
        if together is None
        else (
            f"; {speed.TOGETHER} landing processes started together on empty caches all took "
            f"their first step within {together:.1f} s (one alone: "
            f"{wall[('landing', 'cold')]:.1f} s, whole processes)"
        )
    )
    return (
        f"The first step of each new scene kind compiles its kernels: {both('landing')} for a "
        f"box on the ground, {both('splitting')} for a free body, in the speed run's fresh "
        f"processes{reuse}{crowd}; the compiled code is cached on disk for later processes."
    )


def main_job_summary(doc: dict) -> str:
    """One line per env of a main job's record (``python -m agents``, ``OUT/main_job.json``):
    the training it did, where, and what the learned policy reached."""
    lines = [
        "| env | algorithm | env steps | training | steps/s | physics | physics share "
        "| learned success | analytic success |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for env_id in doc["envs"]:
        result = doc["results"][env_id]
        tp = result["throughput"]
        rows = {row["policy"]: row for row in result["rows"]}
        learned = next(row for name, row in rows.items() if name.endswith("(best_model.zip)"))
        lines.append(
            f"| {env_id} | {result['algo'].upper()} | {tp['env_steps']:,d} "
            f"| {tp['learn_seconds'] / 60:.1f} min | {tp['steps_per_second']:,.0f} "
            f"| {result['backend']} | {tp['sim_share']:.0%} | {learned['success_rate']:.1%} "
            f"| {rows['analytic']['success_rate']:.1%} |"
        )
    lines += ["", f"Whole job (training, evaluation, clips): {doc['wall_seconds'] / 60:.1f} min."]
    return "\n".join(lines)


# NAME -> (JSON file in docs/results, renderer)
RENDERERS: dict[str, tuple[str, Callable[[dict], str]]] = {
    "accuracy": ("accuracy.json", accuracy_summary),
    "stability": ("stability.json", stability_summary),
    "speed": ("speed.json", speed_summary),
    "speed-targets": ("speed.json", speed_targets),
    "compile": ("speed.json", compile_summary),
    # Copies of a main job's records: OUT/main_job.json and OUT/<env>/main_job.json.
    "main-job": ("main-job.json", main_job_summary),
    "main-job-reorient": ("main-job-reorient.json", rows_table),
    "main-job-box-landing": ("main-job-box-landing.json", rows_table),
}


def render(text: str, results: Path = RESULTS) -> str:
    """``text`` with every marked block regenerated from its JSON."""

    def block(match: re.Match) -> str:
        name = match.group(2)
        if name not in RENDERERS:
            raise ValueError(f"unknown results block {name!r}; known: {sorted(RENDERERS)}")
        file, renderer = RENDERERS[name]
        doc = json.loads((results / file).read_text())
        return match.group(1) + renderer(doc).strip() + "\n" + match.group(4)

    return BLOCK.sub(block, text)


PROG = "python -m rigid_env.bench.readme"


def main(argv: Sequence[str] | None = None) -> int:
    parser = cli.Parser(
        prog=PROG, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "files",
        nargs="*",
        type=Path,
        default=list(PAGES),
        help="default: README.md, docs/results.md",
    )
    parser.add_argument("--results", type=Path, default=RESULTS)
    parser.add_argument("--check", action="store_true", help="exit 1 if a page is stale")
    args = parser.parse_args(argv)
    stale = []
    for path in args.files:
        if not path.is_file():
            raise cli.UsageError(f"{path} is not a file")
        text = path.read_text()
        try:
            new = render(text, args.results)
        except (OSError, ValueError) as error:  # a missing or unreadable record, an unknown block
            raise cli.UsageError(f"--results: cannot render the tables from {args.results}: "
                                 f"{type(error).__name__}: {error}") from None  # fmt: skip
        if new == text:
            continue
        if args.check:
            stale.append(path)
            continue
        from rigid_env.files import write_text

        write_text(path, new)
        print(f"rewrote the generated tables of {path}")
    for path in stale:
        print(f"{path}: generated tables differ from {args.results}; rerun without --check")
    return 1 if stale else 0


if __name__ == "__main__":
    sys.exit(cli.run(main, PROG))
