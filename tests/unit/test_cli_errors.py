"""The command line's refusals as pure logic: settings messages, problem and output checks, tables.

Each refusal must be one line naming the thing and the reason, and never quote a secret. The
same paths through real ``trajopt`` processes are in ``tests/e2e/test_cli_paths.py``.
"""

from __future__ import annotations

import argparse
import json
import os
import socket
from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest
from pydantic import ValidationError

from app.cli import _build_parser, _port
from app.keys_cli import database_problem, key_table, safe_url
from app.server import BindError, listen_socket
from app.settings import (
    ConfigurationError,
    Settings,
    env_name,
    get_settings,
    load_settings,
    secret_problem,
    settings_problems,
)
from worker.solver.cli import (
    MAX_ISSUE_LINES,
    InputError,
    check_output,
    issue_lines,
    load_problem,
    looks_like_path,
    scenario_table,
    unknown_scenario_message,
    write_result,
)
from worker.solver.scenarios import UnknownScenarioError, get_scenario, list_scenarios

SHORT_SECRET = "hunter2-but-only-24-chars"


@pytest.fixture
def clean_env(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Iterator[pytest.MonkeyPatch]:
    """No service variables from the calling shell; the settings cache cleared around the test."""
    for name in list(os.environ):
        if name.startswith("TRAJOPT_") or name in ("DATABASE_URL", "REDIS_URL"):
            monkeypatch.delenv(name)
    monkeypatch.setenv("TRAJOPT_DATA_DIR", str(tmp_path / "data"))
    get_settings.cache_clear()
    yield monkeypatch
    get_settings.cache_clear()


def _problems(monkeypatch: pytest.MonkeyPatch, **env: str) -> list[str]:
    for name, value in env.items():
        monkeypatch.setenv(name, value)
    with pytest.raises(ConfigurationError) as caught:
        load_settings()
    return caught.value.problems


def test_a_misspelled_auth_mode_names_the_variable_the_value_and_the_choices(
    clean_env: pytest.MonkeyPatch,
) -> None:
    (line,) = _problems(clean_env, TRAJOPT_AUTH_MODE="api-key")
    assert line.startswith("TRAJOPT_AUTH_MODE: ")
    assert "'single-user'" in line and "'api-keys'" in line and "(got 'api-key')" in line


def test_each_bad_setting_is_its_own_line(clean_env: pytest.MonkeyPatch) -> None:
    lines = _problems(clean_env, TRAJOPT_PORT="abc", TRAJOPT_MAX_NODES="1")
    assert len(lines) == 2
    assert lines[0].startswith("TRAJOPT_PORT: ") and "(got 'abc')" in lines[0]
    assert lines[1].startswith("TRAJOPT_MAX_NODES: ") and "greater than or equal to 3" in lines[1]
    assert all("\n" not in line for line in lines)


@pytest.mark.parametrize(
    ("secret", "reason"),
    [("", "is not set"), ("changeme", "well-known default"), (SHORT_SECRET, "too short")],
)
def test_a_refused_secret_is_named_with_its_reason_and_never_quoted(
    clean_env: pytest.MonkeyPatch, secret: str, reason: str
) -> None:
    (line,) = _problems(clean_env, TRAJOPT_AUTH_MODE="api-keys", TRAJOPT_API_KEY_SECRET=secret)
    assert line.startswith("TRAJOPT_API_KEY_SECRET ") and reason in line
    if secret:
        assert secret not in line


def test_the_secret_is_a_secret_str_that_never_shows_in_a_repr(tmp_path: Path) -> None:
    secret = "0f" * 32
    settings = Settings(data_dir=tmp_path, auth_mode="api-keys", api_key_secret=secret)
    assert settings.api_key_secret.get_secret_value() == secret
    assert secret not in repr(settings) and secret not in str(settings.model_dump())


def test_no_piece_of_a_refused_secret_is_in_the_problems(tmp_path: Path) -> None:
    with pytest.raises(ValidationError) as caught:  # its str() quotes the input: never printed
        Settings(data_dir=tmp_path, auth_mode="api-keys", api_key_secret=SHORT_SECRET)
    text = "\n".join(settings_problems(caught.value))
    pieces = {SHORT_SECRET[i : i + 6] for i in range(len(SHORT_SECRET) - 5)}
    assert not [piece for piece in pieces if piece in text]


def test_values_of_url_settings_are_not_shown(tmp_path: Path) -> None:
    url = "postgresql://trajopt:postgres@db:5432/trajopt"
    with pytest.raises(ValidationError) as caught:
        Settings(
            data_dir=tmp_path, auth_mode="api-keys", api_key_secret="ab" * 32, database_url=url
        )
    (line,) = settings_problems(caught.value)
    assert "DATABASE_URL" in line and "postgres@" not in line


def test_env_name_is_the_variable_actually_set(clean_env: pytest.MonkeyPatch) -> None:
    assert env_name("auth_mode") == "TRAJOPT_AUTH_MODE"
    assert env_name("database_url") == "DATABASE_URL"
    clean_env.setenv("TRAJOPT_DATABASE_URL", "sqlite:///x.db")
    assert env_name("database_url") == "TRAJOPT_DATABASE_URL"
    assert env_name("broker_url") == "TRAJOPT_BROKER_URL"
    clean_env.setenv("REDIS_URL", "redis://localhost/0")
    assert env_name("broker_url") == "REDIS_URL"


def test_secret_problem() -> None:
    assert secret_problem("  ") == "is not set"
    assert secret_problem("Password") == "is a well-known default"
    assert secret_problem("x" * 31) == "is too short"
    assert secret_problem("x" * 32) is None


def test_an_unknown_scenario_is_a_key_error_with_a_suggestion_and_no_quotes() -> None:
    with pytest.raises(KeyError) as caught:  # the type every caller catches
        get_scenario("rlv-min-heatload")
    exc = caught.value
    assert isinstance(exc, UnknownScenarioError)
    assert exc.suggestions == ["rlv-min-heat-load"]
    assert str(exc) == str(exc.args[0])  # no KeyError repr quotes
    assert str(exc) == "unknown scenario 'rlv-min-heatload'; did you mean 'rlv-min-heat-load'?"
    cli = unknown_scenario_message(exc)
    assert "did you mean 'rlv-min-heat-load'?" in cli and "`trajopt scenarios`" in cli


def test_an_unknown_scenario_far_from_all_lists_the_known_ones() -> None:
    with pytest.raises(UnknownScenarioError) as caught:
        get_scenario("zz" * 200)
    assert caught.value.suggestions == []
    assert "known scenarios: cav-h-min-time, " in str(caught.value)
    known = ", ".join(s.name for s in list_scenarios())
    assert str(caught.value).endswith(known)
    assert len(str(caught.value)) < len(known) + 100  # the long name is cut


@pytest.mark.parametrize(
    ("source", "expected"),
    [("p.json", True), ("dir/p", True), ("./p", True), ("rlv-min-heat-load", False)],
)
def test_looks_like_path(source: str, expected: bool) -> None:
    assert looks_like_path(source) is expected


def _refusal(source: str) -> str:
    with pytest.raises(InputError) as caught:
        load_problem(source)
    return str(caught.value)


def test_problem_sources_that_cannot_be_read(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    assert _refusal("missing.json") == "no such file: missing.json"
    assert _refusal("sub/problem") == "no such file: sub/problem"
    assert "unknown scenario 'rlv-min-heatload'" in _refusal("rlv-min-heatload")
    (tmp_path / "folder").mkdir()
    assert _refusal("folder") == "folder is a directory, not a problem file"
    (tmp_path / "broken.json").write_text('{\n  "vehicle": {,\n}', encoding="utf-8")
    assert _refusal("broken.json").startswith("broken.json: invalid JSON at line 2 column 15: ")
    (tmp_path / "list.json").write_text("[1, 2]", encoding="utf-8")
    assert _refusal("list.json") == (
        "list.json: a problem document must be a JSON object, not an array"
    )
    (tmp_path / "latin1.json").write_bytes(b'{"name": "\xe9"}')
    assert _refusal("latin1.json") == "latin1.json: not UTF-8 text (byte 10)"
    (tmp_path / "wrapped.json").write_text('{"problem": 3}', encoding="utf-8")
    assert _refusal("wrapped.json") == (
        'wrapped.json: "problem" must be a JSON object, not a number'
    )


def test_a_scenario_file_and_a_scenario_name_load_the_same_document(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    scenario = get_scenario("rlv-min-heat-load")
    (tmp_path / "s.json").write_text(json.dumps({"problem": scenario.problem}), encoding="utf-8")
    assert load_problem("s.json") == load_problem("rlv-min-heat-load") == scenario.problem


def test_output_paths_are_checked_before_any_work(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    check_output("r.json")  # a new file in a writable folder
    (tmp_path / "old.json").write_text("{}", encoding="utf-8")
    check_output("old.json")  # an existing writable file
    for output, expected in [
        ("missing/dir/r.json", "cannot write output missing/dir/r.json: directory missing/dir"),
        (".", "output . is a directory"),
        ("old.json/r.json", "old.json is not a directory"),
    ]:
        with pytest.raises(InputError, match=expected):
            check_output(output)


def test_a_write_that_fails_at_the_end_is_one_line(tmp_path: Path) -> None:
    gone = tmp_path / "gone"
    gone.mkdir()
    target = gone / "r.json"
    check_output(str(target))
    gone.rmdir()  # removed while the solve ran
    with pytest.raises(InputError) as caught:
        write_result(str(target), {"status": "succeeded"})
    assert str(caught.value) == f"cannot write the result to {target}: No such file or directory"


def test_issue_lines_are_one_per_issue_and_capped() -> None:
    issues = [SimpleNamespace(field=f"f{i}", message="bad") for i in range(MAX_ISSUE_LINES + 3)]
    lines = issue_lines("invalid problem p.json", issues)  # type: ignore[arg-type]
    assert len(lines) == MAX_ISSUE_LINES + 1
    assert lines[0] == "error: invalid problem p.json: f0: bad"
    assert lines[-1] == "error: invalid problem p.json: and 3 more issues"


def test_the_scenario_table_is_aligned_on_the_data() -> None:
    scenarios = list_scenarios()
    lines = scenario_table(scenarios)
    header, rows = lines[0], lines[1::2]
    sources = lines[2::2]
    assert len(rows) == len(sources) == len(scenarios)
    title_at = header.index("TITLE")
    for row, scenario, source in zip(rows, scenarios, sources, strict=True):
        assert row.startswith(scenario.name + " ")
        assert row[title_at:] == scenario.title
        assert row[title_at - 1] == " " and row[title_at - 2] == " "
        assert source[:title_at].strip() == "" and source[title_at:].startswith("source: ")
    longest = max(len(s.name) for s in scenarios)
    assert header.index("METHOD") == longest + 2  # the widest name sets the column


def test_the_key_table_is_aligned_on_the_data() -> None:
    created = datetime(2025, 1, 2, 3, 4, 5, tzinfo=UTC)
    rows: list[Any] = [
        SimpleNamespace(id="a" * 36, client="c", prefix="tj_abc", created_at=created,
                        revoked_at=None),
        SimpleNamespace(id="b" * 36, client="a-much-longer-client-name", prefix="tj_def",
                        created_at=created, revoked_at=created),
    ]  # fmt: skip
    header, *lines = key_table(rows)
    assert header.split() == ["id", "client", "prefix", "created", "revoked"]
    for line in lines:
        assert line.index("tj_") == header.index("prefix")
        assert line.split()[-1] in ("-", created.isoformat(timespec="seconds"))


def test_database_problems_hide_the_password_and_the_statement() -> None:
    url = "postgresql://u:pw-not-shown@db/x"
    assert safe_url(url) == "postgresql://u:***@db/x"
    exc = OSError(20, "Not a directory", "/etc/passwd/x")
    assert database_problem(exc, url) == (
        "cannot use the database postgresql://u:***@db/x: Not a directory: /etc/passwd/x"
    )


def test_usage_errors_are_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as caught:
        _build_parser().parse_args(["solve", "x", "--nodes", "abc"])
    assert caught.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "argument --nodes: not a whole number: 'abc'" in err
    assert "`trajopt solve --help`" in err


@pytest.mark.parametrize("text", ["0", "70000", "-1", "http"])
def test_ports_outside_the_range_are_refused(text: str) -> None:
    with pytest.raises(argparse.ArgumentTypeError):
        _port(text)
    assert _port("8000") == 8000


def test_a_port_in_use_is_refused_before_serving() -> None:
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        with pytest.raises(BindError, match=f"cannot listen on 127.0.0.1:{port}: .*--port"):
            listen_socket("127.0.0.1", port)
    with pytest.raises(BindError, match=r"cannot listen on no-such-host\.invalid:8000"):
        listen_socket("no-such-host.invalid", 8000)
    free = listen_socket("127.0.0.1", 0)
    with free:
        assert free.getsockname()[1] > 0
