"""Examples of the OpenAPI document: request bodies, result documents, histories and errors."""

from __future__ import annotations

import json
from importlib.resources import files
from typing import Any

from app.schemas import RLV_MIN_HEAT_LOAD, ProblemDocument

JOB_ID = "3f2b8c1e-6d0a-4c55-9d1e-2a7f3b9c4e10"
"""The job id of the examples."""

PROBLEM_EXAMPLES: dict[str, dict[str, Any]] = {
    "scenario": {
        "summary": "A built-in scenario, made small",
        "description": "The scenario's problem with fewer nodes and iterations merged in.",
        "value": {
            "scenario": "rlv-min-heat-load",
            "overrides": {"method": {"nodes": 20, "max_iterations": 10}},
        },
    },
    "scenario_method": {
        "summary": "A built-in scenario with method options",
        "value": {"scenario": "rlv-min-heat-load", "method": {"nodes": 60, "time_limit_s": 60}},
    },
    "document": {
        "summary": "A full problem document",
        "value": RLV_MIN_HEAT_LOAD,
    },
}

VALIDATE_EXAMPLES: dict[str, dict[str, Any]] = {
    "document": PROBLEM_EXAMPLES["document"],
    "invalid": {
        "summary": "A document with several errors (all are reported)",
        "value": {
            **RLV_MIN_HEAT_LOAD,
            "vehicle": {**RLV_MIN_HEAT_LOAD["vehicle"], "mass_kg": -1},
            "method": {"name": "energy-scp", "nodes": 1},
            "unknown_field": True,
        },
    },
}


def _example_result(name: str) -> dict[str, Any]:
    """A result document stored beside this module (``example_result_<name>.json``)."""
    text = files("app.routes").joinpath(f"example_result_{name}.json").read_text("utf-8")
    document: dict[str, Any] = json.loads(text)
    return document


RESULT_SUCCEEDED = _example_result("succeeded")
"""``trajopt solve rlv-max-terminal-velocity --nodes 15``: the history cut to its first and last
record, the platform string shortened; everything else as the solver wrote it."""
RESULT_FAILED = _example_result("failed")
"""``trajopt solve rlv-min-heat-load --nodes 21`` (too few nodes: the propagated controls miss
the terminal targets), cut the same way."""

RESULT_EXAMPLES: dict[str, dict[str, Any]] = {
    "succeeded": {
        "summary": "Succeeded (rlv-max-terminal-velocity, 15 nodes)",
        "description": "A real result; its history is cut to the first and last iteration.",
        "value": RESULT_SUCCEEDED,
    },
    "verification_failed": {
        "summary": "Failed: converged, but the propagated controls miss the targets",
        "description": "rlv-min-heat-load with 21 nodes; history cut to the first and last.",
        "value": RESULT_FAILED,
    },
}

PROBLEM_DOCUMENT_EXAMPLES: dict[str, dict[str, Any]] = {
    "scenario": {
        "summary": "rlv-min-heat-load as solved (every default filled in)",
        "value": ProblemDocument.model_validate(RLV_MIN_HEAT_LOAD).model_dump(mode="json"),
    },
}

HISTORY_EXAMPLES: dict[str, dict[str, Any]] = {
    "succeeded": {
        "summary": "Finished job (first and last iteration shown)",
        "value": {
            "job_id": JOB_ID,
            "status": "succeeded",
            "iterations": RESULT_SUCCEEDED["history"],
        },
    },
    "running": {
        "summary": "Running job after its first iteration",
        "value": {
            "job_id": JOB_ID,
            "status": "running",
            "iterations": RESULT_FAILED["history"][:1],
        },
    },
}


def _error(status: int, summary: str, body: dict[str, Any], **top: Any) -> dict[str, Any]:
    """An OpenAPI example of an error answered with ``status``; ``top``: members beside it."""
    error = {"field": None, **body}
    return {
        "summary": f"{error['code']}: {summary}",
        "x-status": status,
        "value": {"error": error, **top},
    }


def _invalid(code: str, what: str, *issues: tuple[str, str, str]) -> dict[str, Any]:
    """The body of a 422 listing ``issues`` (field, message, code) as the service words it."""
    field, message, _ = issues[0]
    return {
        "code": code,
        "message": f"the {what} has {len(issues)} error(s); first: {field}: {message}",
        "field": field,
        "issues": [{"field": f, "message": m, "code": c} for f, m, c in issues],
    }


ERROR_EXAMPLES: dict[str, dict[str, Any]] = {
    "malformed_body": _error(
        400,
        "the body is not decodable JSON (here cut off after its first member name)",
        {
            "code": "malformed_body",
            "message": "the body is not valid JSON: Expecting value at line 1, column 14 "
            "(character 13)",
        },
    ),
    "missing_api_key": _error(
        401,
        "no X-API-Key header",
        {"code": "missing_api_key", "message": "send an API key in the X-API-Key header"},
    ),
    "invalid_api_key": _error(
        401,
        "unknown or revoked key",
        {"code": "invalid_api_key", "message": "the API key is not valid"},
    ),
    "job_not_found": _error(
        404,
        "no such job (or another client's)",
        {"code": "job_not_found", "message": f"no job '{JOB_ID}'"},
    ),
    "scenario_not_found": _error(
        404,
        "no such scenario",
        {
            "code": "scenario_not_found",
            "message": "unknown scenario 'rlv-min-heatload'; did you mean 'rlv-min-heat-load'?",
        },
    ),
    "job_not_finished": _error(
        409,
        "the job is still queued or running",
        {
            "code": "job_not_finished",
            "message": f"job {JOB_ID} is queued; its result is not ready",
        },
    ),
    "result_unavailable": _error(
        409,
        "the job ended without a result",
        {
            "code": "result_unavailable",
            "message": f"job {JOB_ID} ended cancelled without a result: cancelled: cancelled "
            "on request before it started",
        },
    ),
    "batch_not_found": _error(
        404,
        "no such batch of yours",
        {"code": "batch_not_found", "message": f"no batch '{JOB_ID}'"},
    ),
    "invalid_batch": _error(
        422,
        "a child (or the request, or the base problem) is invalid",
        _invalid(
            "invalid_batch",
            "batch",
            (
                "children[0].no_fly_zones[0].radius_deg",
                'Input should be greater than 0 (child 0: {"/no_fly_zones/0/radius_deg": -1.0})',
                "greater_than",
            ),
        ),
    ),
    "no_trajectory": _error(
        409,
        "the result holds no trajectory",
        {"code": "no_trajectory", "message": f"job {JOB_ID}: the result has no trajectory"},
    ),
    "plot_not_found": _error(
        404,
        "no plot of that name for this result",
        {
            "code": "plot_not_found",
            "field": "name",
            "message": f"job {JOB_ID} has no plot 'ground-track'; its plots: convergence",
        },
    ),
    "plot_format_not_found": _error(
        404,
        "no such plot format",
        {
            "code": "plot_format_not_found",
            "field": "fmt",
            "message": "no plot format 'jpg'; formats: png, svg",
        },
    ),
    "job_finished": _error(
        409,
        "nothing left to cancel",
        {"code": "job_finished", "message": f"job {JOB_ID} already ended succeeded"},
    ),
    "body_too_large": _error(
        413,
        "over TRAJOPT_MAX_BODY_BYTES",
        {
            "code": "body_too_large",
            "message": "the request body exceeds the limit of 1048576 bytes",
        },
    ),
    "unsupported_media_type": _error(
        415,
        "the body is not labelled as JSON",
        {
            "code": "unsupported_media_type",
            "message": "the body must be JSON sent with Content-Type: application/json; got "
            "Content-Type: text/plain",
            "field": "Content-Type",
        },
    ),
    "invalid_problem": _error(
        422,
        "every invalid field of the problem",
        _invalid(
            "invalid_problem",
            "problem",
            ("vehicle.mass_kg", "Input should be greater than 0", "greater_than"),
            ("method.nodes", "Input should be greater than or equal to 2", "greater_than_equal"),
        ),
    ),
    "invalid_request": _error(
        422,
        "the scenario request itself",
        _invalid(
            "invalid_request",
            "request",
            ("nodes", "unknown field: not part of the problem contract", "extra_forbidden"),
        ),
    ),
    "invalid_parameter": _error(
        422,
        "a query, path or header parameter",
        {
            "code": "invalid_request",
            "message": "1 invalid field(s): limit: Input should be greater than or equal to 1",
            "field": "limit",
            "issues": [
                {
                    "field": "limit",
                    "message": "Input should be greater than or equal to 1",
                    "code": "greater_than_equal",
                }
            ],
        },
    ),
    "over_server_cap": _error(
        422,
        "over a cap the operator set",
        {
            "code": "over_server_cap",
            "message": "the problem exceeds 1 server cap(s); first: method.nodes: 1500 exceeds "
            "the server cap TRAJOPT_MAX_NODES=1000",
            "field": "method.nodes",
            "issues": [
                {
                    "field": "method.nodes",
                    "message": "1500 exceeds the server cap TRAJOPT_MAX_NODES=1000",
                    "code": "server_cap",
                }
            ],
        },
    ),
    "invalid_idempotency_key": _error(
        422,
        "empty, too long or unprintable",
        {
            "code": "invalid_idempotency_key",
            "message": "Idempotency-Key must be 1..255 printable characters",
            "field": "Idempotency-Key",
        },
    ),
    "idempotency_key_reused": _error(
        422,
        "the same key with another body",
        {
            "code": "idempotency_key_reused",
            "message": "Idempotency-Key 'nightly-42' was already used with a different body",
            "field": "Idempotency-Key",
        },
    ),
    "rate_limited": _error(
        429,
        "retry after Retry-After seconds",
        {"code": "rate_limited", "message": "too many read requests: at most 1200 per 60 s"},
    ),
    "submit_rate_limited": _error(
        429,
        "retry after Retry-After seconds",
        {"code": "rate_limited", "message": "too many submit requests: at most 60 per 60 s"},
    ),
    "too_many_active_jobs": _error(
        429,
        "retry after Retry-After seconds",
        {
            "code": "too_many_active_jobs",
            "message": "client has 100 queued or running jobs; the cap is 100 "
            "(TRAJOPT_MAX_ACTIVE_JOBS)",
        },
    ),
    "too_many_streams": _error(
        429,
        "close a stream, or retry after Retry-After seconds",
        {
            "code": "too_many_streams",
            "message": "too many event streams: this client has 10 event streams open, at most "
            "10 (TRAJOPT_MAX_STREAMS_PER_CLIENT); close one, or retry after 5 s",
        },
    ),
    "too_many_renders": _error(
        429,
        "this client's plots wait to be rendered; retry after Retry-After seconds",
        {
            "code": "too_many_renders",
            "message": "this client has 16 plots waiting or rendering, at most 16 "
            "(TRAJOPT_RENDER_QUEUE_PER_CLIENT); retry after 2 s",
        },
    ),
    "render_unavailable": _error(
        503,
        "a render process stopped and is being replaced; retry after Retry-After seconds",
        {
            "code": "render_unavailable",
            "message": "a plot-rendering process stopped; it is being restarted, retry after 2 s",
        },
    ),
    "database_unavailable": _error(
        503,
        "the database is unreachable; retry after Retry-After seconds",
        {
            "code": "database_unavailable",
            "message": "the database is unreachable; retry after 5 s",
        },
    ),
    "queue_unavailable": _error(
        503,
        "nothing was stored; retry after Retry-After seconds",
        {
            "code": "queue_unavailable",
            "message": "the queue is unreachable; nothing was stored, retry later",
        },
    ),
    "not_ready": _error(
        503,
        "a dependency is unreachable",
        {"code": "not_ready", "message": "local: local job pool not running"},
        checks={"database": "ok", "local": "local job pool not running"},
    ),
}
"""One example per error code, each a body the service answers (``x-status`` names the status);
the OpenAPI document attaches them to the responses of the operations that can give them."""
