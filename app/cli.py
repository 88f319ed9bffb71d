"""The ``trajopt`` command: list scenarios, solve in-process, submit to a service and fetch a
job's problem, run the API or a worker, and manage API keys.

Every refusal is one ``error: …`` line on stderr (one per bad setting or per document issue),
never a traceback. Exit codes:

- 0: done (for ``solve``: solved and verified);
- 1: the solve failed (its reason is printed), or ``keys revoke`` matched no single active key;
- 2: invalid input or configuration (arguments, problem file, output path, ``TRAJOPT_*``
  settings, database URL, broker, port);
- 130: interrupted (Ctrl+C).

An unexpected exception is one line too; ``TRAJOPT_DEBUG=1`` shows its traceback instead.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from typing import Any, NoReturn

from app.settings import ConfigurationError, Settings, load_settings

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_INVALID = 2
EXIT_INTERRUPTED = 130


class CommandError(Exception):
    """Input or configuration a subcommand refuses (exit 2); the message is one line."""


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line with a pointer to ``--help``."""

    def error(self, message: str) -> NoReturn:
        """Print ``prog: error: message`` and exit 2 (argparse would print the usage too)."""
        self.exit(EXIT_INVALID, f"{self.prog}: error: {message} (see `{self.prog} --help`)\n")


def _port(text: str) -> int:
    """A TCP port number, 1..65535."""
    try:
        port = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a port number: {text!r}") from None
    if not 1 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"port {port} is outside 1..65535")
    return port


def _positive_int(text: str) -> int:
    """A whole number of at least 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def _int(text: str) -> int:
    """A whole number (the problem contract checks its range and names the field)."""
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None


def _build_parser() -> argparse.ArgumentParser:
    """The ``trajopt`` argument parser with its subcommands."""
    parser = _Parser(
        prog="trajopt",
        description="Hypersonic entry trajectory optimization by sequential convex programming.",
        epilog="Exit codes: 0 done (solved and verified), 1 solve failed, "
        "2 invalid input or configuration, 130 interrupted.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    sub.add_parser("scenarios", help="list the built-in scenarios")

    solve = sub.add_parser("solve", help="solve a scenario or a problem file in this process")
    solve.add_argument("problem", help="a built-in scenario name or a path to a problem JSON file")
    solve.add_argument(
        "--method",
        help="solution method (default: the document's, else auto: the methods that accept "
        "the problem, in a documented order)",
    )
    solve.add_argument("--nodes", type=_int, help="number of discretization nodes")
    solve.add_argument("-o", "--output", help="write the result document to this JSON file")
    solve.add_argument("-q", "--quiet", action="store_true", help="no per-iteration progress")
    solve.add_argument(
        "--csv", help="also write the trajectory as CSV (one row per node, units in the header)"
    )

    submit = sub.add_parser("submit", help="submit a problem to a running service (and wait)")
    from app.submit_cli import add_arguments as add_submit_arguments

    add_submit_arguments(submit)

    problem = sub.add_parser(
        "problem", help="print the problem document a service job solves (as stored)"
    )
    from app.submit_cli import add_problem_arguments

    add_problem_arguments(problem)

    plot = sub.add_parser("plot", help="render the plots of a result document (PNG or SVG)")
    plot.add_argument("result", help="a result document (trajopt solve -o, or GET /result)")
    plot.add_argument("-o", "--output", required=True, help="directory for the plot files")
    plot.add_argument(
        "--format",
        dest="formats",
        action="append",
        choices=("png", "svg"),
        help="file format (repeatable; default png)",
    )
    plot.add_argument("--only", action="append", metavar="NAME", help="only these plots")

    serve = sub.add_parser("serve", help="run the HTTP API")
    serve.add_argument("--host", default=None, help="bind address (default from settings)")
    serve.add_argument("--port", type=_port, default=None, help="port (default from settings)")

    worker = sub.add_parser("worker", help="run a Celery worker against the configured broker")
    worker.add_argument("--concurrency", type=_positive_int, default=None, help="worker processes")

    keys = sub.add_parser("keys", help="manage API keys (api-keys mode)")
    keys_sub = keys.add_subparsers(dest="keys_command", required=True, metavar="ACTION")
    create = keys_sub.add_parser("create", help="create a key for a client and print it once")
    create.add_argument("--client", required=True, help="client name owning the key's jobs")
    listing = keys_sub.add_parser("list", help="list keys (never the keys themselves)")
    listing.add_argument("--client", default=None, help="only this client's keys")
    revoke = keys_sub.add_parser("revoke", help="revoke a key by its id (or a unique id prefix)")
    revoke.add_argument("key_id", help="the id shown by `trajopt keys list`")
    return parser


def check_database(settings: Settings) -> None:
    """Refuse a database URL that does not parse, and a SQLite folder that cannot be created."""
    from sqlalchemy import make_url
    from sqlalchemy.exc import ArgumentError

    try:
        url = make_url(settings.effective_database_url)
    except ArgumentError:
        raise CommandError(
            "DATABASE_URL is not a database URL (expected e.g. postgresql://user:pass@host/db)"
        ) from None
    if url.get_backend_name() != "sqlite" or not url.database or url.database == ":memory:":
        return
    folder = os.path.dirname(url.database) or "."
    try:
        os.makedirs(folder, exist_ok=True)
    except OSError as exc:
        raise CommandError(
            f"TRAJOPT_DATA_DIR: cannot create {folder}: {exc.strerror or exc}"
        ) from None
    if not os.access(folder, os.W_OK | os.X_OK):
        raise CommandError(f"TRAJOPT_DATA_DIR: {folder} is not writable")


def _serve(args: argparse.Namespace) -> int:
    """``trajopt serve``: settings and database URL checked, the port bound, then uvicorn."""
    settings = load_settings()
    check_database(settings)
    from app.server import BindError, run_server

    try:
        run_server(host=args.host, port=args.port)  # binds before it touches any stored job
    except BindError as exc:
        raise CommandError(str(exc)) from None
    return EXIT_OK


def _worker(args: argparse.Namespace) -> int:
    """``trajopt worker``: its refusals (no broker, limits, database) become exit 2."""
    settings = load_settings()
    if settings.uses_broker:  # without one, run_worker says so first
        check_database(settings)
    from sqlalchemy.exc import SQLAlchemyError

    from app.keys_cli import database_problem
    from worker.run import run_worker

    try:
        run_worker(concurrency=args.concurrency)
    except SystemExit as exc:
        if isinstance(exc.code, str):  # run_worker's refusals (no broker, limits)
            raise CommandError(exc.code) from None
        raise
    except SQLAlchemyError as exc:  # the migration at start-up
        raise CommandError(database_problem(exc, settings.effective_database_url)) from None
    return EXIT_OK


def _dispatch(args: argparse.Namespace) -> int:
    """Run the chosen subcommand; its exit code."""
    if args.command in ("scenarios", "solve"):
        from worker.solver import cli as solver_cli

        def csv_table(result: dict[str, Any]) -> str:
            from app.report import trajectory_csv

            return trajectory_csv(result)

        return solver_cli.run(args, csv_table)
    if args.command in ("submit", "problem"):
        from app import submit_cli

        server = args.server or os.environ.get("TRAJOPT_SERVER") or submit_cli.DEFAULT_SERVER
        api_key = args.api_key or os.environ.get("TRAJOPT_API_KEY")
        if args.command == "problem":
            return submit_cli.fetch_problem(args, server, api_key)
        return submit_cli.run(args, server, api_key)
    if args.command == "plot":
        from app.report.files import plot_command

        try:
            return plot_command(args.result, args.output, args.formats or ["png"], args.only)
        except ValueError as exc:
            raise CommandError(str(exc)) from None
    if args.command == "serve":
        return _serve(args)
    if args.command == "worker":
        return _worker(args)
    if args.command == "keys":
        from app.keys_cli import run_keys

        return run_keys(args)
    return EXIT_INVALID


def _first_line(exc: BaseException) -> str:
    """``Type: first line of the message`` of an unexpected exception."""
    lines = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {lines[0]}" if lines else type(exc).__name__


def _quiet_stdout() -> None:
    """Point stdout at /dev/null so the interpreter's final flush cannot fail again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the console script; returns the process exit code."""
    try:
        args = _build_parser().parse_args(argv)
        return _dispatch(args)
    except ConfigurationError as exc:
        for problem in exc.problems:
            print(f"error: {problem}", file=sys.stderr)
        return EXIT_INVALID
    except CommandError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_INVALID
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # e.g. `trajopt scenarios | head -1`
        _quiet_stdout()
        return EXIT_FAILED
    except Exception as exc:
        if os.environ.get("TRAJOPT_DEBUG"):
            raise
        print(
            f"error: unexpected {_first_line(exc)} (TRAJOPT_DEBUG=1 shows the traceback)",
            file=sys.stderr,
        )
        return EXIT_FAILED


QUICK_EXIT_COMMANDS = frozenset({"solve"})
"""One-shot commands that end the process at once after their output: no interpreter
teardown, which after a solve (compiled kernels, the helper thread, scipy and numba state)
took about half a second of a two-second run; every file they write is closed by then."""


def entry() -> None:
    """The ``trajopt`` console script: ``main``, then the exit (quick after a one-shot command)."""
    argv = sys.argv[1:]
    code = main(argv)
    if argv and argv[0] in QUICK_EXIT_COMMANDS:
        try:
            sys.stdout.flush()
            sys.stderr.flush()
        except (BrokenPipeError, ValueError):
            _quiet_stdout()
            code = code or EXIT_FAILED
        os._exit(code)
    sys.exit(code)


if __name__ == "__main__":
    entry()
