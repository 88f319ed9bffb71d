"""The fingerprint of a problem document: SHA-256 of its canonical JSON.

Canonical JSON is what Python's ``json.dumps(document, sort_keys=True, separators=(",", ":"))``
writes: keys sorted, no whitespace, non-ASCII characters escaped as ``\\uXXXX``, numbers in
Python's shortest round-trip form (``105000.0``, ``9.4369e-05``). Anyone holding the document as
solved (``GET /v1/jobs/{id}/problem``) recomputes the result's ``provenance.problem_sha256``
with those two lines.
"""

from __future__ import annotations

import hashlib
import json
from typing import Any

from app.schemas.problem import ProblemDocument


def canonical_json(document: Any) -> str:
    """``document`` as canonical JSON text (keys sorted, no whitespace)."""
    return json.dumps(document, sort_keys=True, separators=(",", ":"))


def document_sha256(document: Any) -> str:
    """SHA-256 (hex) of ``document``'s canonical JSON in UTF-8."""
    return hashlib.sha256(canonical_json(document).encode("utf-8")).hexdigest()


def problem_sha256(problem: ProblemDocument) -> str:
    """The fingerprint of a validated problem as solved: its normalized document (every
    default filled in, as the service stores it) hashed in canonical JSON."""
    return document_sha256(problem.model_dump(mode="json"))
