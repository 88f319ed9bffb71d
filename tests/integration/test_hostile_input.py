"""Hostile input against a real API on PostgreSQL (api-keys mode): never a 5xx, never a dropped
keep-alive connection, and another client's reads stay fast while one posts invalid megabytes.

NUL characters only fail on PostgreSQL (text and jsonb refuse U+0000), so this runs on the
integration stack, not on SQLite.
"""

from __future__ import annotations

import http.client
import json
import statistics
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from app.schemas import RLV_MIN_HEAT_LOAD
from tests.integration.harness import SCENARIO, ApiServer, create_api_key

pytestmark = pytest.mark.slow

UNKNOWN_JOB = "3f2b8c1e-6d0a-4c55-9d1e-2a7f3b9c4e10"


def _nested(depth: int) -> str:
    return "[" * depth + "1" + "]" * depth


def _doc(**changes: Any) -> dict[str, Any]:
    document = json.loads(json.dumps(RLV_MIN_HEAT_LOAD))
    document.update(changes)
    return document


def _megabyte(limit: int) -> bytes:
    """A body filling ``limit`` with invalid items (a table axis of strings)."""
    aoa = {"mode": "table", "velocity_m_s": [0, 1], "alpha_deg": ["x"] * (limit // 5)}
    vehicle = {**RLV_MIN_HEAT_LOAD["vehicle"], "angle_of_attack": aoa}
    raw = json.dumps(_doc(vehicle=vehicle), separators=(",", ":")).encode()
    assert len(raw) <= limit
    return raw


def _hostile() -> list[tuple[str, str, str, bytes | None, dict[str, str]]]:
    """(label, method, path, body, headers) of every hostile request."""
    scenario = f'{{"scenario": "{SCENARIO}", '
    mass = json.dumps(_doc()).replace('"mass_kg": ', '"mass_kg": NaN, "x_": ')
    cases: list[tuple[str, str, str, bytes | None, dict[str, str]]] = [
        ("nul name", "POST", "/v1/jobs", json.dumps(_doc(name="a\x00b")).encode(), {}),
        (
            "nul validate",
            "POST",
            "/v1/problems/validate",
            json.dumps(_doc(description="\x00")).encode(),
            {},
        ),
        (
            "nul zone",
            "POST",
            "/v1/jobs",
            json.dumps(
                {"scenario": SCENARIO, "overrides": {"no_fly_zones": [{"name": "\x00"}]}}
            ).encode(),
            {},
        ),
        ("nan + key", "POST", "/v1/jobs", mass.encode(), {"Idempotency-Key": "hostile-nan"}),
        (
            "infinity + key",
            "POST",
            "/v1/jobs",
            (scenario + '"overrides": {"vehicle": {"mass_kg": -Infinity}}}').encode(),
            {"Idempotency-Key": "hostile-inf"},
        ),
        ("surrogate", "POST", "/v1/jobs", b'{"scenario": "\\ud800"}', {}),
        (
            "mass 1e308",
            "POST",
            "/v1/jobs",
            json.dumps(_doc(vehicle={**RLV_MIN_HEAT_LOAD["vehicle"], "mass_kg": 1e308})).encode(),
            {},
        ),
    ]
    for depth in (10, 100, 500, 999, 1000, 10_000):
        for where in ("overrides", "method"):
            body = f'{scenario}"{where}": {{"x": {_nested(depth)}}}}}'.encode()
            cases.append((f"depth {depth} {where}", "POST", "/v1/jobs", body, {}))
    for suffix, method in (("", "GET"), ("/result", "GET"), ("/history", "GET"), ("", "DELETE")):
        for ident in ("%00", "a%00b", "%ED%A0%80", "x" * 4000):
            cases.append(
                (f"job id {ident[:8]}{suffix}", method, f"/v1/jobs/{ident}{suffix}", None, {})
            )
    cases.append(("events %00", "GET", "/v1/jobs/%00/events", None, {}))
    return cases


@pytest.fixture(scope="module")
def other_key(stack_env: dict[str, str]) -> str:
    """A key of a second client, whose reads are timed."""
    return create_api_key(stack_env, "hostile-other")


def test_hostile_input_gets_4xx_on_one_kept_connection(api: ApiServer, api_key: str) -> None:
    host, port = "127.0.0.1", api.port
    connection = http.client.HTTPConnection(host, port, timeout=30)
    connection.connect()
    socket_used = connection.sock
    cases = _hostile()
    cases.append(("1 MB invalid", "POST", "/v1/problems/validate", _megabyte(1_048_576), {}))
    answers: dict[str, int] = {}
    try:
        for label, method, path, body, extra in cases:
            headers = {"X-API-Key": api_key, "Content-Type": "application/json", **extra}
            connection.request(method, path, body=body, headers=headers)
            response = connection.getresponse()
            payload = response.read()
            answers[label] = response.status
            assert 400 <= response.status < 500, (label, response.status, payload[:300])
            error = json.loads(payload)["error"]
            assert error["code"] and error["message"], label
            if response.status == 422:
                assert error["field"] is not None, (label, error)
            assert response.getheader("connection") != "close", label
            assert connection.sock is socket_used, f"{label}: the connection was dropped"
    finally:
        connection.close()
    assert answers["nul name"] == answers["nul validate"] == 422
    assert answers["nan + key"] == 422
    assert all(answers[f"job id %00{s}"] == 404 for s in ("", "/result", "/history"))
    assert "internal_error" not in api.log_text()


def _post_invalid_megabytes(base: int, key: str, stop: threading.Event, sent: list[int]) -> None:
    body = _megabyte(1_048_576)
    connection = http.client.HTTPConnection("127.0.0.1", base, timeout=30)
    headers = {"X-API-Key": key, "Content-Type": "application/json"}
    try:
        while not stop.is_set():
            connection.request("POST", "/v1/problems/validate", body=body, headers=headers)
            response = connection.getresponse()
            response.read()
            assert response.status == 422
            sent.append(1)
    finally:
        connection.close()


def _cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / 100.0  # utime + stime, in clock ticks


@pytest.mark.exclusive
def test_reads_stay_fast_while_another_client_posts_invalid_megabytes(
    api: ApiServer, api_key: str, other_key: str
) -> None:
    """Two posting threads keep the API busy with 1 MB invalid bodies; another client's reads
    must keep a p95 of at most 100 ms. Before the bounds, such posts cost seconds of API CPU
    each and reads reached a p95 of 2.3 s. 100 ms is the acceptance figure; a read alone takes
    a few ms and about 15 ms under these posts (the client's lane caps its share of the API's
    time), so the margin absorbs a two-core machine shared with the posting threads."""
    stop = threading.Event()
    sent: list[int] = []
    assert api.process is not None
    cpu_before = _cpu_s(api.process.pid)
    posters = [
        threading.Thread(target=_post_invalid_megabytes, args=(api.port, api_key, stop, sent))
        for _ in range(2)
    ]
    for poster in posters:
        poster.start()
    reader = http.client.HTTPConnection("127.0.0.1", api.port, timeout=30)
    latencies: list[float] = []
    try:
        time.sleep(0.5)
        deadline = time.monotonic() + 6.0
        while time.monotonic() < deadline:
            started = time.perf_counter()
            reader.request("GET", "/v1/jobs?limit=5", headers={"X-API-Key": other_key})
            response = reader.getresponse()
            response.read()
            latencies.append(time.perf_counter() - started)
            assert response.status == 200
            time.sleep(0.02)
    finally:
        stop.set()
        for poster in posters:
            poster.join(timeout=30)
        reader.close()
    cpu_per_body = (_cpu_s(api.process.pid) - cpu_before) / max(1, len(sent))
    p95 = statistics.quantiles(latencies, n=20)[18]
    print(
        f"posts={len(sent)} reads={len(latencies)} p95={p95 * 1000:.1f} ms "
        f"api cpu per 1 MB body={cpu_per_body * 1000:.0f} ms"
    )
    assert len(sent) >= 10, "the posting threads did not load the API"
    assert p95 <= 0.100, f"p95 of reads {p95 * 1000:.0f} ms during invalid posts"
    assert cpu_per_body < 0.25, f"{cpu_per_body:.3f} s of API CPU per invalid megabyte"
