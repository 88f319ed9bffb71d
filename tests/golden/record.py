"""Record the golden outputs: ``python -m tests.golden.record [case ...]`` (all by default)."""

from __future__ import annotations

import argparse
import json

from tests.golden.cases import (
    CPU_KEY,
    DATA,
    VERSIONS_FILE,
    cases,
    cpu_target,
    library_versions,
    solve,
)


def main(names: list[str]) -> None:
    """Solve each named case (every case without names) and write its golden file."""
    DATA.mkdir(exist_ok=True)
    every = cases()
    for name in names or sorted(every):
        out = solve(every[name])
        (DATA / f"{name}.json").write_text(json.dumps(out, indent=1, sort_keys=True) + "\n")
        print(f"{name}: {out['status']}, {len(out.get('history', []))} iterations")
    recorded = {**library_versions(), CPU_KEY: cpu_target()}
    versions = json.dumps(recorded, indent=1, sort_keys=True)
    (DATA / VERSIONS_FILE).write_text(versions + "\n")


def parser() -> argparse.ArgumentParser:
    """The command's argument parser, apart so a test checks the documented commands against it."""
    cli = argparse.ArgumentParser(prog="python -m tests.golden.record", description=__doc__)
    cli.add_argument("cases", nargs="*", metavar="case", help="case names (default: every case)")
    return cli


if __name__ == "__main__":
    main(parser().parse_args().cases)
