"""Typed FastAPI dependencies: the service state, its parts and the caller's identity.

They are ``async`` so that FastAPI resolves them on the event loop instead of spending a
thread-pool round trip on each: those that may do I/O (the API key's lookup, a rate limit
counted in Redis) hand only that I/O to the thread pool, and only when there is some to do.
"""

from __future__ import annotations

import re
from typing import Annotated

from fastapi import Depends, Request, Security
from fastapi.security import APIKeyHeader
from starlette.concurrency import run_in_threadpool

from app.auth import API_KEY_HEADER, Principal, authenticate
from app.dispatch import Dispatcher
from app.errors import ApiError, not_found
from app.ratelimit import AuthFailures, Kind
from app.settings import Settings
from app.state import ServiceState
from app.storage.session import Database

api_key_header = APIKeyHeader(
    name=API_KEY_HEADER,
    auto_error=False,
    description="The client's API key (api-keys mode); created with `trajopt keys create`.",
)


async def get_service(request: Request) -> ServiceState:
    """The service state created at start-up."""
    service: ServiceState = request.app.state.service
    return service


ServiceDep = Annotated[ServiceState, Depends(get_service)]


async def get_settings_dep(service: ServiceDep) -> Settings:
    """The settings the application was created with."""
    return service.settings


async def get_database_dep(service: ServiceDep) -> Database:
    """The job database."""
    return service.database


async def get_dispatcher(service: ServiceDep) -> Dispatcher:
    """The dispatcher that hands jobs to workers."""
    return service.dispatcher


_JOB_ID = re.compile(r"[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12}")
"""The form of every job id (a UUID in canonical form); nothing else can name a job."""


async def get_principal(
    request: Request,
    service: ServiceDep,
    api_key: Annotated[str | None, Security(api_key_header)] = None,
) -> Principal:
    """The authenticated caller (in api-keys mode a database lookup, made in the thread pool).

    It guards every route of a job too: a ``job_id`` that is no job id (``%00``, megabytes, ...)
    is the 404 of an unknown job once the caller is known, and never reaches the database.
    """
    if service.settings.auth_mode == "single-user":  # no I/O: no thread-pool round trip
        principal = authenticate(service.database, service.settings, api_key)
    else:
        address = request.client.host if request.client is not None else "unknown"
        principal = await run_in_threadpool(_authenticated, service, api_key, address)
    for kind in ("job", "batch"):  # both ids are UUIDs
        ident = request.path_params.get(f"{kind}_id")
        if isinstance(ident, str) and _JOB_ID.fullmatch(ident) is None:
            raise not_found(kind, ident if len(ident) <= 64 else f"{ident[:64]}...")
    return principal


def _authenticated(service: ServiceState, api_key: str | None, address: str) -> Principal:
    """The principal of a key (a database lookup; run in the thread pool). An address that
    failed too often is answered 429 before the lookup; every 401 counts against it."""
    failures = AuthFailures(service.rate_limiter, service.settings, address)
    refusal = failures.refusal() if failures.limited else None
    if refusal is not None:
        raise ApiError(429, "rate_limited", refusal.message, headers=refusal.headers)
    try:
        return authenticate(service.database, service.settings, api_key)
    except ApiError as exc:
        if exc.status == 401 and failures.limited:
            failures.note_failure()
        raise


PrincipalDep = Annotated[Principal, Depends(get_principal)]


async def _limit(service: ServiceState, principal: Principal, kind: str) -> str:
    """Charge a read, or test a submission's rejected-submission window, against the caller's
    client's and key's moving windows (429 with Retry-After when one is full); returns the
    owner for the route: the client's name, carrying its quota for a submission (the submit
    use case tests and uses the submit window itself, once it knows the request is no replay)."""
    quota = service.rate_limiter.quota(service.settings, principal.client, principal.key_id)
    counted: Kind = "read" if kind == "read" else "rejected"
    count = quota.charge if kind == "read" else quota.check
    if not quota.limits(counted):  # nothing to count: no thread-pool round trip
        refusal = None
    elif service.rate_limiter.blocking:
        refusal = await run_in_threadpool(count, counted)
    else:  # counted in memory, in microseconds
        refusal = count(counted)
    if refusal is not None:
        raise ApiError(429, "rate_limited", refusal.message, headers=refusal.headers)
    return principal.client if kind == "read" else quota.submitter()


async def get_owner(service: ServiceDep, principal: PrincipalDep) -> str:
    """The caller's client name, after counting one read against its rate limits."""
    return await _limit(service, principal, "read")


async def get_submitter(service: ServiceDep, principal: PrincipalDep) -> str:
    """The caller's client name with its quota, once its rejected-submission window admits
    one more (a client refused too often is answered 429 before its body is looked at)."""
    return await _limit(service, principal, "submit")


SettingsDep = Annotated[Settings, Depends(get_settings_dep)]
DatabaseDep = Annotated[Database, Depends(get_database_dep)]
DispatcherDep = Annotated[Dispatcher, Depends(get_dispatcher)]
OwnerDep = Annotated[str, Depends(get_owner)]
SubmitterDep = Annotated[str, Depends(get_submitter)]
