"""``python -m rigid_env.bench {accuracy,stability,speed,all} [--quick] [--out DIR]``.

Each command prints a markdown table and writes ``DIR/<command>.json`` and ``DIR/<command>.png``
(atomically, replacing the previous ones). The default is the full run (5–8 minutes per command);
``--quick`` takes about a minute per command; ``--preset tiny`` (seconds, used by the tests)
exercises every code path. ``--out`` is checked before measuring; a mistake in the arguments
exits with status 2 and one line on stderr; a fault of the file system while writing (no space,
file too large, permission, read-only) with status 74 and one line naming the file, the files
written before it whole.
"""

from __future__ import annotations

import importlib
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from .. import cli
from . import report

COMMANDS = ("accuracy", "stability", "speed")
PROG = "python -m rigid_env.bench"


def run_command(
    command: str, preset: str, out: Path, progress: report.Progress | None = None
) -> tuple[dict[str, Any], str]:
    module = importlib.import_module(f"rigid_env.bench.{command}")
    start = time.perf_counter()
    result = module.measure(preset, progress=progress)
    result["bench_wall_s"] = time.perf_counter() - start
    report.write_json(out / f"{command}.json", command, preset, result)
    module.plot(result, out / f"{command}.png")
    return result, module.table(result)


def main(argv: Sequence[str] | None = None) -> int:
    parser = cli.Parser(prog=PROG, description=__doc__.split("\n")[0], epilog=cli.EXIT_STATUSES)
    parser.add_argument("command", choices=(*COMMANDS, "all"))
    parser.add_argument("--quick", action="store_true", help="each command in under a minute")
    parser.add_argument("--preset", choices=("full", "quick", "tiny"), help="overrides --quick")
    parser.add_argument("--out", type=Path, default=Path("reports"), help="output directory")
    parser.add_argument("--verbose", "-v", action="store_true", help="progress on stderr")
    args = parser.parse_args(argv)
    commands = COMMANDS if args.command == "all" else (args.command,)
    for command in commands:  # every output checked before the first measurement
        for suffix in (".json", ".png"):
            cli.writable_file(args.out / (command + suffix), "--out")
    preset = args.preset or ("quick" if args.quick else "full")
    progress = (lambda msg: print(msg, file=sys.stderr, flush=True)) if args.verbose else None
    for command in commands:
        result, text = run_command(command, preset, args.out, progress)
        print(f"## {command} ({preset}, {result['bench_wall_s']:.0f} s)\n\n{text}\n")
        print(f"wrote {args.out / (command + '.json')} and {args.out / (command + '.png')}\n")
    return 0


if __name__ == "__main__":
    sys.exit(cli.run(main, PROG))
