"""Reading a JSON request body: after authentication, off the event loop, with a cheap shape check.

The routes that take a problem read their body through :func:`problem_body` instead of letting
FastAPI parse it, so that

* the caller is authenticated first: a malformed body without a key is a 401, not a 400/422;
* decoding and checking run in the thread pool (only bodies of at most
  :data:`INLINE_DECODE_BYTES`, which take microseconds, are decoded on the event loop), and a
  client's large bodies are read and decoded one at a time, within a share of the process's
  time (:mod:`app.body_lanes`);
* a structural check bounds the work before validation: no value nests deeper than
  :data:`MAX_DEPTH`, no array has more than :data:`MAX_ARRAY_ITEMS` items, no object more than
  :data:`MAX_OBJECT_MEMBERS` members, there are at most :data:`MAX_CONTAINERS` arrays and
  objects in all, and no string holds a NUL character or an unpaired
  surrogate (neither can be stored in PostgreSQL nor written as UTF-8). Every bound lies far
  above what the problem contract can use, so only hostile or broken bodies meet them; each
  such body is a 422 naming the field and the bound, found in one pass over the decoded value.
"""

from __future__ import annotations

import json
import re
from email.message import Message
from typing import Annotated, Any

from fastapi import Depends, Request
from starlette.concurrency import run_in_threadpool

from app.body_lanes import is_large
from app.deps import PrincipalDep, ServiceDep
from app.errors import ApiError, malformed_json, undecodable_body
from app.schemas import FieldIssue, dotted_path

MAX_DEPTH = 32
"""Deepest nesting of arrays and objects in a body (the contract needs 6, with overrides)."""
MAX_ARRAY_ITEMS = 1000
"""Longest array in a body (the contract's longest is a table axis of 200 points)."""
MAX_OBJECT_MEMBERS = 100
"""Most members of one object in a body (the contract's largest object has fewer than 50)."""
MAX_CONTAINERS = 5000
"""Most arrays and objects in a body (a document with two 200-row tables has about 500)."""
INLINE_DECODE_BYTES = 4096
"""Bodies up to this size (a scenario request, a small problem) are decoded on the event loop:
that takes microseconds, less than handing them to the thread pool and back."""

Path = tuple[str | int, ...]

_SUSPECT_TEXT = re.compile(r"\\u0000|\\u[dD][89a-fA-F]")
"""JSON escapes that may decode to a NUL or a surrogate: only then are strings checked one by
one (a raw control character is already a decoding error, a raw surrogate non-ASCII text)."""
_BAD_CHARACTER = re.compile("[\x00\ud800-\udfff]")
_TOKEN = re.compile(r'"(?:[^"\\]|\\.)*"|[\[\]{},:]|[^\s"\[\]{},:]+|\s+')


def _text_issue(path: Path, text: str) -> FieldIssue | None:
    """The issue of a string (a member name or a value) that cannot be stored, or None."""
    found = _BAD_CHARACTER.search(text)
    if found is None:
        return None
    if found.group() == "\x00":
        message = "contains a NUL character (U+0000), which cannot be stored"
        return FieldIssue(field=dotted_path(path), message=message, code="nul_character")
    message = (
        f"contains an unpaired surrogate (U+{ord(found.group()):04X}), which is not a character"
    )
    return FieldIssue(field=dotted_path(path), message=message, code="invalid_text")


def _too_deep(path: Path) -> FieldIssue:
    return FieldIssue(
        field=dotted_path(path),
        message=f"nests arrays and objects more than {MAX_DEPTH} levels deep",
        code="too_deep",
    )


def structure_issue(value: Any, check_text: bool = True) -> FieldIssue | None:
    """The first place where ``value`` (a decoded JSON body) breaks a bound, or None.

    One iterative pass over the containers (no recursion, however deep the value); strings are
    looked at only when ``check_text``.
    """
    stack: list[tuple[Any, Path]] = [(value, ())]
    containers = 0
    while stack:
        node, path = stack.pop()
        if isinstance(node, str):
            issue = _text_issue(path, node)
            if issue is not None:
                return issue
            continue
        if not isinstance(node, dict | list):
            continue
        if len(path) >= MAX_DEPTH:
            return _too_deep(path)
        containers += 1
        if containers > MAX_CONTAINERS:
            return FieldIssue(
                field=dotted_path(path),
                message=f"is past the limit of {MAX_CONTAINERS} arrays and objects in one body",
                code="too_many_containers",
            )
        if isinstance(node, dict):
            if len(node) > MAX_OBJECT_MEMBERS:
                return FieldIssue(
                    field=dotted_path(path),
                    message=f"has {len(node)} members; at most {MAX_OBJECT_MEMBERS} are accepted",
                    code="too_many_members",
                )
            if check_text:
                for key in node:
                    if (issue := _text_issue((*path, key), key)) is not None:
                        return issue
            items: list[tuple[str | int, Any]] = list(node.items())
        else:
            if len(node) > MAX_ARRAY_ITEMS:
                return FieldIssue(
                    field=dotted_path(path),
                    message=f"has {len(node)} items; at most {MAX_ARRAY_ITEMS} are accepted",
                    code="too_many_items",
                )
            items = list(enumerate(node))
        kinds = (dict, list, str) if check_text else (dict, list)
        stack.extend(
            (item, (*path, name)) for name, item in reversed(items) if isinstance(item, kinds)
        )
    return None


def _deep_location(text: str) -> Path:
    """Where ``text`` (JSON too deep for the decoder) first nests more than ``MAX_DEPTH`` levels.

    Scans tokens only up to that point, which the decoder has passed: every string before it
    is well formed, so the scan is linear.
    """
    frames: list[list[Any]] = []  # [is_object, current key or index, expecting a key]
    for match in _TOKEN.finditer(text):
        token = match.group()
        if token in ("{", "["):
            if len(frames) >= MAX_DEPTH:
                return tuple(frame[1] for frame in frames)
            frames.append([token == "{", 0 if token == "[" else "", token == "{"])
        elif token in ("}", "]"):
            if frames:
                frames.pop()
        elif token == ",":
            if frames and frames[-1][0]:
                frames[-1][2] = True
            elif frames:
                frames[-1][1] += 1
        elif token == ":":
            if frames:
                frames[-1][2] = False
        elif token.startswith('"') and frames and frames[-1][0] and frames[-1][2]:
            frames[-1][1] = json.loads(token)
    return tuple(frame[1] for frame in frames)


def _is_json(content_type: str) -> bool:
    message = Message()
    message["content-type"] = content_type
    subtype = message.get_content_subtype()
    return message.get_content_maintype() == "application" and (
        subtype == "json" or subtype.endswith("+json")
    )


def _refused(issue: FieldIssue) -> ApiError:
    return ApiError(
        422,
        "invalid_request",
        f"the request has 1 error(s); first: {issue.field or '(document)'}: {issue.message}",
        field=issue.field,
        issues=[issue.model_dump()],
    )


def decode_body(raw: bytes, content_type: str | None) -> Any:
    """The decoded JSON of a request body, or the ``ApiError`` (400, 415, 422) refusing it."""
    if not raw:
        raise malformed_json(json.JSONDecodeError("Expecting value", "", 0))
    if not content_type or not _is_json(content_type):
        sent = f"Content-Type: {content_type}" if content_type else "no Content-Type"
        raise ApiError(
            415,
            "unsupported_media_type",
            f"the body must be JSON sent with Content-Type: application/json; got {sent}",
            field="Content-Type",
        )
    try:
        text = raw.decode(json.detect_encoding(raw), "surrogatepass")  # as json.loads does
    except UnicodeDecodeError:
        raise undecodable_body(raw) from None
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise malformed_json(exc) from None
    except RecursionError:
        raise _refused(_too_deep(_deep_location(text))) from None
    check_text = not text.isascii() or _SUSPECT_TEXT.search(text) is not None
    issue = structure_issue(value, check_text)
    if issue is not None:
        raise _refused(issue)
    return value


async def problem_body(request: Request, service: ServiceDep, principal: PrincipalDep) -> Any:
    """The request's JSON body, read once the caller is authenticated, decoded in a thread; a
    large body through its client's lane (:mod:`app.body_lanes`)."""
    content_type = request.headers.get("content-type")
    if not is_large(request.headers.get("content-length")):
        raw = await request.body()
        if len(raw) <= INLINE_DECODE_BYTES:  # microseconds: less than a thread-pool round trip
            return decode_body(raw, content_type)
        return await run_in_threadpool(decode_body, raw, content_type)
    async with service.body_lanes.lane(principal.client):
        raw = await request.body()
        return await run_in_threadpool(decode_body, raw, content_type)


ProblemBody = Annotated[Any, Depends(problem_body)]
"""A route parameter holding the decoded body of a problem submission or validation."""


def problem_request_body(examples: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """``openapi_extra`` of a route taking a :data:`ProblemBody`: its required JSON body with
    ``examples`` (the schema, a problem or a scenario request, is set by ``app.openapi``)."""
    return {
        "x-problem-body": True,
        "requestBody": {
            "required": True,
            "content": {"application/json": {"schema": {}, "examples": examples}},
        },
    }
