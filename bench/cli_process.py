"""The whole ``trajopt solve`` process against the solve it reports, per built-in scenario.

Each run starts ``trajopt solve <scenario> -o <file>`` as a new process and times it from its
start to its exit; the result's ``timing.total_s`` (model building, kernel loading, the
optimization and the verification) is the solve itself, and the difference is what the process
adds: interpreter start, imports, argument and file handling, exit. Medians over the runs (the
first run is a warm-up: file caches). Aim: at most 1.0 s above the solve on an idle machine.

    python -m bench.cli_process [--runs 5] [--only NAME ...]
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from worker.solver.scenarios import list_scenarios


def _trajopt() -> list[str]:
    """The console script beside this interpreter, else the module."""
    script = Path(sys.executable).with_name("trajopt")
    if script.exists():
        return [str(script)]
    found = shutil.which("trajopt")
    return [found] if found else [sys.executable, "-m", "app.cli"]


def measure(name: str, runs: int) -> dict[str, float]:
    """Median process wall time, reported total_s and their difference for ``name``."""
    command = _trajopt()
    walls, totals = [], []
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "result.json"
        for run in range(runs + 1):
            start = time.perf_counter()
            subprocess.run(
                [*command, "solve", name, "-o", str(out)],
                check=True,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
            wall = time.perf_counter() - start
            if run == 0:
                continue  # warm-up
            walls.append(wall)
            totals.append(float(json.loads(out.read_text())["timing"]["total_s"]))
    overheads = [w - t for w, t in zip(walls, totals, strict=True)]
    return {
        "process_s": statistics.median(walls),
        "total_s": statistics.median(totals),
        "overhead_s": statistics.median(overheads),
        "overhead_max_s": max(overheads),
    }


def parser() -> argparse.ArgumentParser:
    """main()'s argument parser, apart so a test checks the documented commands against it."""
    cli = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    cli.add_argument("--runs", type=int, default=5)
    cli.add_argument("--only", nargs="*", default=None, help="scenario names (default: all)")
    return cli


def main() -> None:
    args = parser().parse_args()
    names = args.only or [s.name for s in list_scenarios()]
    print("| scenario | process s | solve (total_s) s | process - solve s (median) | max |")
    print("|---|---|---|---|---|")
    for name in names:
        row = measure(name, args.runs)
        print(
            f"| {name} | {row['process_s']:.2f} | {row['total_s']:.2f} | "
            f"{row['overhead_s']:.2f} | {row['overhead_max_s']:.2f} |"
        )


if __name__ == "__main__":
    main()
