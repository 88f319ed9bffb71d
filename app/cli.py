"""The ``trajopt`` command: list scenarios, solve in-process, run the API or a worker, and manage
API keys."""

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

    keys = sub.add_parser("keys", help="manage API keys (api-keys mode)")
    keys_sub = keys.add_subparsers(dest="keys_command", required=True)
    create = keys_sub.add_parser("create", help="create a key for a client and print it once")
    create.add_argument("--client", required=True, help="client name owning the key's jobs")
    listing = keys_sub.add_parser("list", help="list keys (never the keys themselves)")
    listing.add_argument("--client", default=None, help="only this client's keys")
    revoke = keys_sub.add_parser("revoke", help="revoke a key by its id (or a unique id prefix)")
    revoke.add_argument("key_id", help="the id shown by `trajopt keys list`")
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
    if args.command == "keys":
        from app.keys_cli import run_keys

        return run_keys(args)
    return 2


if __name__ == "__main__":
    sys.exit(main())
