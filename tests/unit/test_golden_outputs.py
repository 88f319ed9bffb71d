"""The solver reproduces its recorded golden outputs exactly (``tests/golden``).

Tolerance: none. Each case is solved in this process with the same arithmetic in the same
order as when it was recorded, so every float of the result document (iterates' history,
objective, trajectory, verification) must be bitwise equal; only wall-clock figures and the
environment are left out (``tests.golden.cases.VOLATILE_KEYS``). Two recordings in a row were
identical, so any difference is a change of the arithmetic, not noise. The arithmetic is that of
the numerical libraries the recordings were made with (``data/versions.json``, pinned in
constraints.txt, which the CI installs): with other versions the comparison is skipped, with the
reason, except under CI, where it fails.
"""

from __future__ import annotations

import json
import os
from typing import Any

import pytest

from tests.golden.cases import DATA, VERSIONS_FILE, cases, library_versions, solve

CASES = cases()


def _first_difference(got: Any, want: Any, path: str = "") -> str | None:
    """Where ``got`` first differs from ``want`` (a JSON path and both values), or None."""
    if isinstance(want, dict) and isinstance(got, dict):
        if set(got) != set(want):
            return f"{path}: keys {sorted(set(got) ^ set(want))} differ"
        for key in want:
            found = _first_difference(got[key], want[key], f"{path}.{key}")
            if found:
                return found
        return None
    if isinstance(want, list) and isinstance(got, list):
        if len(got) != len(want):
            return f"{path}: length {len(got)} != {len(want)}"
        for i, (g, w) in enumerate(zip(got, want, strict=True)):
            found = _first_difference(g, w, f"{path}[{i}]")
            if found:
                return found
        return None
    if got != want or type(got) is not type(want):
        return f"{path}: {got!r} != {want!r}"
    return None


def test_every_case_has_a_recording() -> None:
    recorded = {p.stem for p in DATA.glob("*.json") if p.name != VERSIONS_FILE}
    assert recorded == set(CASES)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(CASES))
def test_reproduces_golden_output(name: str) -> None:
    recorded = json.loads((DATA / VERSIONS_FILE).read_text())
    installed = library_versions()
    if installed != recorded:
        reason = (
            f"recorded with {recorded}, installed {installed}: install with "
            "-c constraints.txt (or re-record: python -m tests.golden.record)"
        )
        if os.environ.get("CI"):
            pytest.fail(reason)
        pytest.skip(reason)
    want = json.loads((DATA / f"{name}.json").read_text())
    got = json.loads(json.dumps(solve(CASES[name]), sort_keys=True))
    difference = _first_difference(got, want)
    assert difference is None, f"{name} moved at {difference}"
