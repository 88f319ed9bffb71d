"""``trajopt submit``: send a problem (a file or a built-in scenario) to a running service with
:class:`app.client.TrajoptClient`, and optionally wait for it, print its progress and save its
result and trajectory CSV. Exit codes as ``trajopt solve``: 0 succeeded, 1 the job did not
succeed, 2 the service refused the problem or could not be reached (one line each).

``trajopt problem``: fetch the problem document a job solves (what its result's
``provenance.problem_sha256`` fingerprints). Exit 0, or 2 when the service refuses or cannot be
reached."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

import httpx

from app.client import (
    ApiError,
    InvalidRequestError,
    JobTimeoutError,
    ServiceUnreachableError,
    TrajoptClient,
)

DEFAULT_SERVER = "http://127.0.0.1:8000"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The ``submit`` subcommand's arguments."""
    parser.add_argument("problem", help="a built-in scenario name or a path to a problem JSON file")
    add_service_arguments(parser)
    parser.add_argument("--nodes", type=int, default=None, help="number of discretization nodes")
    parser.add_argument("--wait", action="store_true", help="wait for the job and report it")
    parser.add_argument(
        "--timeout", type=float, default=600.0, help="with --wait: seconds to wait (default 600)"
    )
    parser.add_argument("-o", "--output", help="with --wait: write the result document here")
    parser.add_argument("--csv", help="with --wait: write the trajectory CSV here")
    parser.add_argument("-q", "--quiet", action="store_true", help="no per-iteration progress")
    parser.add_argument(
        "--retries",
        type=int,
        default=5,
        help="tries again a request that gets no answer, or a 'not now' answer, up to this "
        "many times (waiting 0.5, 1, 2, 4, 8 s, or the service's Retry-After; default 5)",
    )


def add_service_arguments(parser: argparse.ArgumentParser) -> None:
    """Where the service is and the key to it (``submit`` and ``problem``)."""
    parser.add_argument(
        "--server",
        default=None,
        help=f"the service's base URL (default: $TRAJOPT_SERVER or {DEFAULT_SERVER})",
    )
    parser.add_argument("--api-key", default=None, help="API key (default: $TRAJOPT_API_KEY)")


def add_problem_arguments(parser: argparse.ArgumentParser) -> None:
    """The ``problem`` subcommand's arguments."""
    parser.add_argument("job_id", help="the job's id (as trajopt submit printed it)")
    add_service_arguments(parser)
    parser.add_argument("-o", "--output", help="write the document to this file, not stdout")


def fetch_problem(args: argparse.Namespace, server: str, api_key: str | None) -> int:
    """Print (or write to ``--output``) the problem document job ``args.job_id`` solves, and
    its SHA-256 in canonical JSON on stderr; the exit code."""
    from app.schemas.fingerprint import document_sha256
    from worker.solver.cli import InputError, check_output

    try:
        if args.output:
            check_output(args.output)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    with TrajoptClient(server, api_key) as client:
        try:
            problem = client.problem(args.job_id)
        except ApiError as exc:
            print(f"error: the service refused: {exc.code}: {exc.message}", file=sys.stderr)
            return 2
        except httpx.TransportError as exc:
            print(f"error: cannot reach {server}: {exc}", file=sys.stderr)
            return 2
    text = json.dumps(problem, indent=1)
    if args.output:
        with open(args.output, "w", encoding="utf-8") as handle:
            handle.write(text + "\n")
        print(f"problem written to {args.output}", file=sys.stderr)
    else:
        print(text)
    print(f"sha256 {document_sha256(problem)} (canonical JSON)", file=sys.stderr)
    return 0


def request_body(source: str, nodes: int | None) -> dict[str, Any]:
    """The submission: a problem file's document, or ``{"scenario": name}``; ``nodes`` merged
    into its method. A file that cannot be read raises ``InputError``."""
    from worker.solver.cli import looks_like_path, read_problem_file

    if looks_like_path(source):
        body = read_problem_file(source)
        if nodes is not None:
            body["method"] = {**(body.get("method") or {}), "nodes": nodes}
        return body
    body = {"scenario": source}
    if nodes is not None:
        body["method"] = {"nodes": nodes}
    return body


def _progress(record: dict[str, Any]) -> None:
    print(f"iteration {record['iteration']}: cost {record.get('cost')}", file=sys.stderr)


def _report(client: TrajoptClient, job: dict[str, Any], args: argparse.Namespace) -> int:
    """Print the finished job, write the requested files; the exit code."""
    status = job["status"]
    error = job.get("error") or {}
    line = f"job {job['id']} {status}"
    if error:
        line += f": {error.get('code')}: {error.get('message')}"
    print(line, flush=True)
    result: dict[str, Any] | None = None
    if args.output or args.csv:
        try:
            result = client.result(job["id"])
        except ApiError as exc:  # finished without a result (cancelled before it started)
            print(f"error: no result to write: {exc.message}", file=sys.stderr)
            return 1
    if args.output and result is not None:
        with open(args.output, "w", encoding="utf-8") as handle:
            json.dump(result, handle, indent=1)
        print(f"result written to {args.output}", file=sys.stderr)
    if args.csv and result is not None and result.get("trajectory") is not None:
        with open(args.csv, "w", encoding="utf-8") as handle:
            handle.write(client.trajectory_csv(job["id"]))
        print(f"trajectory written to {args.csv}", file=sys.stderr)
    return 0 if status == "succeeded" else 1


def run(args: argparse.Namespace, server: str, api_key: str | None) -> int:
    """Submit, then (``--wait``) follow and report; the exit code."""
    from worker.solver.cli import InputError, check_output

    try:
        for path in (args.output, args.csv):
            if path:
                check_output(path)
        body = request_body(args.problem, args.nodes)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    with TrajoptClient(server, api_key, max_retries=max(args.retries, 0)) as client:
        try:
            job = client.submit(body)
            print(f"job {job['id']} {job['status']}: {server.rstrip('/')}/ui/jobs/{job['id']}")
            if not args.wait:
                return 0
            if not args.quiet:
                for record in client.iterations(job["id"], timeout_s=args.timeout):
                    _progress(record)
            return _report(client, client.wait(job["id"], timeout_s=args.timeout), args)
        except InvalidRequestError as exc:
            for issue in exc.issues or [{"field": exc.field, "message": exc.message}]:
                print(
                    f"error: invalid problem: {issue.get('field')}: {issue.get('message')}",
                    file=sys.stderr,
                )
            return 2
        except ApiError as exc:
            print(f"error: the service refused: {exc.code}: {exc.message}", file=sys.stderr)
            return 2
        except JobTimeoutError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 1
        except ServiceUnreachableError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        except httpx.TransportError as exc:
            print(f"error: cannot reach {server}: {exc}", file=sys.stderr)
            return 2
