"""Response and request models of the HTTP API (the problem document itself is in app.schemas)."""

from __future__ import annotations

from datetime import datetime
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from app.schemas import FieldIssue
from app.schemas.plausibility import PlausibilityWarning
from app.schemas.result import HistoryRecord

JobStatusName = Literal["queued", "running", "succeeded", "failed", "cancelled", "timed_out"]

_JOB_ID = "3f2b8c1e-6d0a-4c55-9d1e-2a7f3b9c4e10"
_TS = "2025-01-01T12:00:00Z"


class ErrorDetail(BaseModel):
    """What went wrong: a stable code, a message, the offending field and, for 422, every issue."""

    code: str = Field(..., description="Machine-readable error code.")
    message: str = Field(..., description="Human-readable explanation.")
    field: str | None = Field(None, description="Dotted path of the offending field, if any.")
    issues: list[FieldIssue] | None = Field(
        None, description="The problems found, at most the first 50 (validation errors only)."
    )
    issues_total: int | None = Field(
        None, description="How many problems there are in all; issues lists at most the first 50."
    )


class ErrorResponse(BaseModel):
    """The body of every error response (each response in the OpenAPI document has examples)."""

    error: ErrorDetail


class ScenarioJobRequest(BaseModel):
    """Submit a built-in scenario, optionally changed by an ``overrides`` JSON Merge Patch."""

    model_config = ConfigDict(
        extra="forbid",
        json_schema_extra={
            "examples": [
                {
                    "scenario": "rlv-min-heat-load",
                    "overrides": {"method": {"nodes": 20, "max_iterations": 10}},
                }
            ]
        },
    )

    scenario: str = Field(..., description="Name of a built-in scenario (see /v1/scenarios).")
    overrides: dict[str, Any] = Field(
        default_factory=dict,
        description="JSON Merge Patch (RFC 7396) of the scenario's problem document: objects "
        "merge member by member, null removes a member, arrays and other values replace. An "
        "object that changes the tag of a discriminated union (vehicle.aerodynamics.model, "
        "vehicle.angle_of_attack.mode, planet.atmosphere.model, terminal.<state>.kind, "
        "final_time.kind, method.name) replaces the scenario's object instead of merging.",
        examples=[
            {"planet": {"atmosphere": {"model": "us76"}}},
            {"method": {"nodes": 40}, "no_fly_zones": None},
        ],
    )
    method: dict[str, Any] | None = Field(
        None,
        description='Method and options merged into the scenario\'s method, e.g. {"nodes": 40}.',
    )


class Progress(BaseModel):
    """Live progress of a running job, written by the worker at each phase and SCP iteration."""

    phase: Literal["loading", "compiling", "optimizing", "verifying", "finished"] | None = Field(
        None,
        description="What the attempt is doing: loading the solver's kernels from numba's "
        "cache, compiling them (once after an install), running SCP iterations, or verifying "
        'the answer by propagation; "finished" once the job has a terminal status (succeeded, '
        "failed, cancelled, timed_out), whatever the attempt last did. A queued job waiting for "
        "the embedded pool to load the solver says loading or compiling; otherwise None while "
        "queued.",
    )
    iteration: int | None = None
    cost: float | None = None
    max_state_change: dict[str, float | None] | float | None = Field(
        None, description="Largest change of each state in the iteration (SI units, degrees)."
    )
    conic_status: str | None = None
    elapsed_s: float | None = Field(None, description="Seconds from the attempt's start.")
    method: str | None = Field(
        None,
        description="Only for a job whose method is auto: the method of the attempt running "
        "now, and once finished the method whose answer the result holds.",
    )


class JobErrorInfo(BaseModel):
    """Why a job did not succeed."""

    code: str
    message: str | None = None


class JobLinks(BaseModel):
    """Where to find the job's parts."""

    self: str
    result: str
    history: str
    events: str
    problem: str = Field(..., description="The problem document as solved.")


class JobView(BaseModel):
    """A job as the API shows it."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "id": _JOB_ID,
                    "status": "running",
                    "owner": "default",
                    "method": "energy-scp",
                    "scenario": "rlv-min-heat-load",
                    "attempts": 1,
                    "max_attempts": 3,
                    "cancel_requested": False,
                    "created_at": _TS,
                    "updated_at": "2025-01-01T12:00:02Z",
                    "started_at": "2025-01-01T12:00:00.050Z",
                    "finished_at": None,
                    "elapsed_s": 1.95,
                    "progress": {
                        "iteration": 4,
                        "cost": 1.93e7,
                        "max_state_change": {"altitude_m": 412.0, "heading_deg": 0.31},
                        "conic_status": "optimal",
                        "elapsed_s": 1.9,
                    },
                    "error": None,
                    "solve_s": None,
                    "links": {
                        "self": f"/v1/jobs/{_JOB_ID}",
                        "result": f"/v1/jobs/{_JOB_ID}/result",
                        "history": f"/v1/jobs/{_JOB_ID}/history",
                        "events": f"/v1/jobs/{_JOB_ID}/events",
                        "problem": f"/v1/jobs/{_JOB_ID}/problem",
                    },
                }
            ]
        }
    )

    id: str
    status: JobStatusName
    owner: str
    method: str
    scenario: str | None = None
    attempts: int = Field(..., description="Times a worker started this job.")
    max_attempts: int
    cancel_requested: bool
    created_at: datetime
    updated_at: datetime
    started_at: datetime | None = Field(None, description="Start of the latest attempt.")
    finished_at: datetime | None = None
    elapsed_s: float | None = Field(
        None, description="Seconds since the latest start (until the end when finished)."
    )
    progress: Progress | None = None
    error: JobErrorInfo | None = None
    solve_s: float | None = Field(None, description="Solver wall time of the finished job.")
    warnings: list[PlausibilityWarning] = Field(
        default_factory=list,
        description="Legal values of the problem far outside what entry vehicles fly (likely "
        "slips of units); they only inform.",
    )
    links: JobLinks


class JobPage(BaseModel):
    """One page of the caller's jobs, newest first."""

    items: list[JobView]
    total: int = Field(..., description="Jobs matching the filter.")
    limit: int
    offset: int
    next_offset: int | None = Field(None, description="Offset of the next page, if any.")


class HistoryView(BaseModel):
    """The convergence history of a job so far (complete once it has finished)."""

    job_id: str
    status: JobStatusName
    iterations: list[HistoryRecord] = Field(
        ..., description="The current attempt's SCP iterations so far, in order."
    )


class ScenarioSummary(BaseModel):
    """A built-in scenario in the listing."""

    name: str
    title: str
    source: str


class ScenarioView(ScenarioSummary):
    """A built-in scenario with its full problem document and the corrections made to it."""

    corrections: list[str]
    problem: dict[str, Any]


class MethodView(BaseModel):
    """A solution method, what it supports and its default options."""

    model_config = ConfigDict(extra="allow")

    name: str
    title: str | None = None
    paper: str | None = None
    features: list[str] = Field(default_factory=list)
    objectives: list[str] = Field(default_factory=list, description="Objective terms it takes.")
    phases: bool = Field(False, description="Whether it solves documents with phases.")
    propulsion: bool = Field(False, description="Whether it flies a vehicle with propulsion.")
    default_options: dict[str, Any] = Field(default_factory=dict)
    preference: int | None = Field(
        None,
        description="Its place in auto's order (1: tried first among those that accept a "
        "problem); null for auto itself.",
    )
    capabilities: dict[str, dict[str, bool]] = Field(
        default_factory=dict,
        description="Its row of the capability matrix: group (final_time, angle_of_attack, "
        "limits, atmosphere, aerodynamics, planet, flight, objectives) -> feature -> whether it "
        "takes it, probed from its own support check (auto: whether any method takes it).",
    )


class ValidationReport(BaseModel):
    """A valid problem, normalized (defaults filled in) as it would be solved, and its legal
    values far outside what entry vehicles fly."""

    valid: Literal[True] = True
    issues: list[FieldIssue] = Field(default_factory=list)
    warnings: list[PlausibilityWarning] = Field(
        default_factory=list,
        description="Legal values far outside what entry vehicles fly (likely slips of units, "
        "e.g. a speed in km/s); the problem is valid and would be solved as it is.",
    )
    problem: dict[str, Any]


class Health(BaseModel):
    """Liveness or readiness report."""

    status: str
    checks: dict[str, str] = Field(default_factory=dict)


class BatchLinks(BaseModel):
    """Where to find a batch's parts."""

    self: str
    summary: str
    summary_csv: str
    plot: str = Field(..., description="The batch's plot; .png or .svg.")


class BatchView(BaseModel):
    """A batch as the API shows it: its children counted by status."""

    id: str
    name: str | None = None
    kind: Literal["grid", "monte_carlo", "methods", "footprint"]
    size: int = Field(..., description="Number of children (each an ordinary job).")
    status: Literal["running", "finished", "cancelled"] = Field(
        ...,
        description="running while a child is queued or running; then finished, or cancelled "
        "when the batch was cancelled.",
    )
    counts: dict[str, int] = Field(..., description="Children per job status.")
    cancel_requested: bool
    created_at: datetime
    links: BatchLinks


class BatchPage(BaseModel):
    """One page of the caller's batches, newest first."""

    items: list[BatchView]
    total: int
    limit: int
    offset: int
    next_offset: int | None = None


class BatchSummary(BaseModel):
    """One row per child, in order: its parameters, status, objective, key terminal and path
    figures (from the verification), iterations and times; null where a child has none yet."""

    batch: BatchView
    parameters: list[str] = Field(..., description="The parameter paths, in column order.")
    rows: list[dict[str, Any]]
