"""The ``trajopt`` command: list scenarios, solve in-process, run the API or a worker."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence


def _build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="trajopt",
        description="Hypersonic entry trajectory optimization by sequential convex programming.",
    )
    sub = parser.add_subparsers(dest="command", required=True)

    sub.add_parser("scenarios", help="list the built-in scenarios")

    solve = sub.add_parser("solve", help="solve a scenario or a problem file in this process")
    solve.add_argument("problem", help="a built-in scenario name or a path to a problem JSON file")
    solve.add_argument(
        "--method", help="solution method (default: the document's, else energy-scp)"
    )
    solve.add_argument("--nodes", type=int, help="number of discretization nodes")
    solve.add_argument("-o", "--output", help="write the result document to this JSON file")
    solve.add_argument("-q", "--quiet", action="store_true", help="no per-iteration progress")

    serve = sub.add_parser("serve", help="run the HTTP API")
    serve.add_argument("--host", default=None, help="bind address (default from settings)")
    serve.add_argument("--port", type=int, default=None, help="port (default from settings)")

    worker = sub.add_parser("worker", help="run a Celery worker against the configured broker")
    worker.add_argument("--concurrency", type=int, default=None, help="worker processes")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the console script; returns the process exit code."""
    args = _build_parser().parse_args(argv)
    if args.command in ("scenarios", "solve"):
        from worker.solver import cli as solver_cli

        return solver_cli.run(args)
    if args.command == "serve":
        from app.server import run_server

        run_server(host=args.host, port=args.port)
        return 0
    if args.command == "worker":
        from worker.run import run_worker

        run_worker(concurrency=args.concurrency)
        return 0
    return 2


if __name__ == "__main__":
    sys.exit(main())
