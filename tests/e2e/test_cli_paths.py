"""Every refusal of the ``trajopt`` command through a real process: one line, the right exit code.

Each test runs ``python -m app.cli`` in a scratch folder with no service variables from the
calling shell (no ``TRAJOPT_*``, ``DATABASE_URL``, ``REDIS_URL``) and the data folder in a
temporary directory. Exit codes: 0 done, 1 solve failed, 2 invalid input or configuration,
130 interrupted.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.integration.harness import free_port, run_cli, service_free_env

pytestmark = pytest.mark.slow

SHORT_SECRET = "s3cr3t-value-too-short-1"
"""A secret under 32 characters: refused, and never to appear in any output."""
GOOD_SECRET = "9f" * 32


@dataclass(frozen=True)
class Run:
    """A finished ``trajopt`` process."""

    code: int
    out: str
    err: str

    @property
    def err_lines(self) -> list[str]:
        """The non-empty lines on stderr."""
        return [line for line in self.err.splitlines() if line.strip()]


Trajopt = Callable[..., Run]
"""``trajopt(*args, **env)``: one finished run of the command."""


def _env(tmp_path: Path, extra: dict[str, str] | None = None) -> dict[str, str]:
    """The calling environment without service variables, the data folder in ``tmp_path``."""
    env = service_free_env()
    env["TRAJOPT_DATA_DIR"] = str(tmp_path / "data")
    env.update(extra or {})
    return env


@pytest.fixture
def trajopt(tmp_path: Path) -> Trajopt:
    """``trajopt(*args, **env)``: run the command in ``tmp_path`` and return its :class:`Run`."""

    def run(*args: str, **env: str) -> Run:
        """Run ``python -m app.cli *args`` with ``env`` added."""
        done = run_cli(*args, env=_env(tmp_path, env), cwd=tmp_path)
        return Run(done.returncode, done.stdout, done.stderr)

    return run


def assert_stderr(run: Run, code: int, *needles: str, lines: int = 1) -> str:
    """``run`` exited ``code`` with ``lines`` lines on stderr, no traceback, each needle in them."""
    assert run.code == code, (run.code, run.err)
    assert "Traceback" not in run.err and "Traceback" not in run.out
    assert len(run.err_lines) == lines, run.err
    for needle in needles:
        assert needle in run.err, (needle, run.err)
    return run.err


# 1. api-keys mode without a secret, or with one too short


@pytest.mark.parametrize(
    "command", [("keys", "list"), ("keys", "create", "--client", "a"), ("serve",)]
)
def test_api_keys_mode_without_a_secret_is_one_line(
    trajopt: Trajopt, command: tuple[str, ...]
) -> None:
    run = trajopt(*command, TRAJOPT_AUTH_MODE="api-keys")
    assert_stderr(run, 2, "TRAJOPT_API_KEY_SECRET is not set", "openssl rand -hex 32")


@pytest.mark.parametrize(
    "command", [("keys", "list"), ("keys", "create", "--client", "a"), ("serve",)]
)
def test_a_short_secret_is_refused_without_showing_it(
    trajopt: Trajopt, command: tuple[str, ...]
) -> None:
    run = trajopt(*command, TRAJOPT_AUTH_MODE="api-keys", TRAJOPT_API_KEY_SECRET=SHORT_SECRET)
    assert_stderr(run, 2, "TRAJOPT_API_KEY_SECRET is too short")
    for piece in (SHORT_SECRET, SHORT_SECRET[:12], SHORT_SECRET[-12:]):
        assert piece not in run.out and piece not in run.err


def test_keys_in_api_keys_mode_work_and_never_print_the_secret(trajopt: Trajopt) -> None:
    env = {"TRAJOPT_AUTH_MODE": "api-keys", "TRAJOPT_API_KEY_SECRET": GOOD_SECRET}
    created = trajopt("keys", "create", "--client", "team-a", **env)
    assert created.code == 0 and created.out.startswith("tj_")
    listed = trajopt("keys", "list", **env)
    assert listed.code == 0 and "team-a" in listed.out and listed.err == ""
    for run in (created, listed):
        assert GOOD_SECRET not in run.out + run.err


# 2. any invalid TRAJOPT_* setting


def test_a_misspelled_auth_mode_names_the_variable_and_the_choices(trajopt: Trajopt) -> None:
    for command in (("keys", "list"), ("serve",), ("worker",)):
        run = trajopt(*command, TRAJOPT_AUTH_MODE="api-key")
        assert_stderr(
            run, 2, "error: TRAJOPT_AUTH_MODE: ", "'single-user' or 'api-keys'", "(got 'api-key')"
        )


def test_every_bad_setting_is_one_line(trajopt: Trajopt) -> None:
    run = trajopt("serve", TRAJOPT_PORT="eighty", TRAJOPT_MAX_NODES="2", TRAJOPT_AUTO_MIGRATE="hm")
    err = assert_stderr(run, 2, "TRAJOPT_PORT: ", "TRAJOPT_MAX_NODES: ", lines=3)
    assert "TRAJOPT_AUTO_MIGRATE: input should be a valid boolean" in err
    assert all(line.startswith("error: TRAJOPT_") for line in run.err_lines)


def test_a_default_database_password_is_named_without_the_url(trajopt: Trajopt) -> None:
    run = trajopt(
        "keys",
        "list",
        TRAJOPT_AUTH_MODE="api-keys",
        TRAJOPT_API_KEY_SECRET=GOOD_SECRET,
        DATABASE_URL="postgresql://trajopt:postgres@db.invalid:5432/trajopt",
    )
    assert_stderr(run, 2, "DATABASE_URL uses a default password")
    assert "postgres@" not in run.err


def test_an_unusable_database_is_one_line_without_its_password(trajopt: Trajopt) -> None:
    closed = free_port()
    url = f"postgresql://u:pw-{closed}-hidden@127.0.0.1:{closed}/x"
    assert_stderr(trajopt("keys", "list", DATABASE_URL=url), 2, "cannot use the database")
    assert_stderr(trajopt("keys", "list", DATABASE_URL="nonsense"), 2, "DATABASE_URL is not")
    run = trajopt("keys", "list", DATABASE_URL=url)
    assert f"pw-{closed}-hidden" not in run.err


# 3. output paths checked before the solve; a write that fails at the end


@pytest.mark.parametrize(
    ("output", "needle"),
    [
        ("missing/dir/r.json", "directory missing/dir does not exist"),
        (".", "output . is a directory"),
    ],
)
def test_an_unwritable_output_is_refused_before_solving(
    trajopt: Trajopt, output: str, needle: str
) -> None:
    run = trajopt("solve", "rlv-min-heat-load", "-o", output)
    assert_stderr(run, 2, needle)
    assert "iter" not in run.err and run.out == ""  # nothing was solved


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write anywhere")
def test_an_output_in_a_read_only_folder_is_refused_before_solving(
    trajopt: Trajopt, tmp_path: Path
) -> None:
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    run = trajopt("solve", "rlv-min-heat-load", "-o", "locked/r.json")
    assert_stderr(run, 2, "no permission to create files in locked")


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full")
def test_a_write_that_fails_after_the_solve_is_one_line(trajopt: Trajopt) -> None:
    run = trajopt("solve", "rlv-min-heat-load", "--nodes", "21", "-q", "-o", "/dev/full")
    assert_stderr(run, 2, "error: cannot write the result to /dev/full: No space left on device")
    assert run.out.startswith("status: ")  # the summary is still shown


def test_a_result_is_written_where_asked(trajopt: Trajopt, tmp_path: Path) -> None:
    run = trajopt("solve", "rlv-min-heat-load", "--nodes", "21", "-q", "-o", "r.json")
    assert run.code in (0, 1) and "Traceback" not in run.err
    result = json.loads((tmp_path / "r.json").read_text(encoding="utf-8"))
    assert run.out.startswith(f"status: {result['status']}")
    assert run.code == (0 if result["status"] == "succeeded" else 1)


def test_a_problem_file_without_a_method_is_solved_by_auto(
    trajopt: Trajopt, tmp_path: Path
) -> None:
    """``trajopt solve`` on a document that names no method: auto picks, the summary says which
    and lists the attempts; a document no method accepts is refused before any work (exit 2)."""
    from worker.solver.scenarios import get_scenario

    document = dict(get_scenario("rlv-min-heat-load").problem)
    document.pop("method")
    (tmp_path / "p.json").write_text(json.dumps(document), encoding="utf-8")
    run = trajopt("solve", "p.json", "--nodes", "41", "-q", "-o", "r.json")
    assert run.code == 0, run.err
    assert run.out.splitlines()[:3] == [
        "status: succeeded",
        "method: auto -> energy-scp",
        run.out.splitlines()[2],
    ]
    assert run.out.splitlines()[2].startswith("  attempt 1 energy-scp (answer): succeeded, ")
    result = json.loads((tmp_path / "r.json").read_text(encoding="utf-8"))
    assert result["attempts"][0]["options"]["nodes"] == 41
    document["final_time"] = {"kind": "fixed", "value_s": 1500.0}
    document["objective"] = "min_control_effort"  # only hp-scp takes it, on a free final time
    (tmp_path / "none.json").write_text(json.dumps(document), encoding="utf-8")
    refused = trajopt("solve", "none.json", "-q")
    assert refused.code == 2 and "Traceback" not in refused.err
    lines = refused.err_lines
    assert lines[0].startswith(
        "error: method auto cannot solve this problem: method: no method accepts this problem"
    )
    assert "hp-scp refuses vehicle.angle_of_attack, final_time" in lines[0]
    assert lines[1] == (
        "error: method auto cannot solve this problem: final_time: energy-scp cannot fix the "
        "final time: energy is its independent variable and time is an outcome; leave "
        "final_time free"
    )
    assert refused.out == ""


# 4. keys in single-user mode


def test_keys_create_in_single_user_mode_says_how_to_switch(trajopt: Trajopt) -> None:
    run = trajopt("keys", "create", "--client", "a")
    assert_stderr(run, 2, "api-keys mode", "TRAJOPT_AUTH_MODE=api-keys", "TRAJOPT_API_KEY_SECRET")


def test_keys_list_and_revoke_in_single_user_mode_work_with_a_note(trajopt: Trajopt) -> None:
    listed = trajopt("keys", "list")
    assert listed.code == 0 and listed.out.split() == [
        "id",
        "client",
        "prefix",
        "created",
        "revoked",
    ]
    assert_stderr(listed, 0, "note: TRAJOPT_AUTH_MODE is single-user")
    missing = trajopt("keys", "revoke", "0000")
    assert_stderr(missing, 1, "no single active key has the id or id prefix '0000'")
    assert_stderr(trajopt("keys", "revoke", " "), 2, "give the id of the key to revoke")


def test_a_key_made_in_api_keys_mode_can_be_revoked_in_single_user_mode(trajopt: Trajopt) -> None:
    env = {"TRAJOPT_AUTH_MODE": "api-keys", "TRAJOPT_API_KEY_SECRET": GOOD_SECRET}
    assert trajopt("keys", "create", "--client", "team-a", **env).code == 0
    key_id = trajopt("keys", "list", **env).out.splitlines()[1].split()[0]
    run = trajopt("keys", "revoke", key_id)
    assert run.out.strip() == f"revoked {key_id}"
    assert_stderr(run, 0, "note: TRAJOPT_AUTH_MODE is single-user")
    assert trajopt("keys", "list", **env).out.splitlines()[1].split()[-1] != "-"


# 5. a misspelled scenario


def test_a_misspelled_scenario_gets_a_suggestion_and_no_quotes_around_the_message(
    trajopt: Trajopt,
) -> None:
    run = trajopt("solve", "rlv-min-heatload")
    err = assert_stderr(run, 2, "did you mean 'rlv-min-heat-load'?", "`trajopt scenarios`")
    assert err.startswith("error: unknown scenario 'rlv-min-heatload'")
    assert '"' not in err


def test_an_unrelated_name_points_to_the_scenario_list(trajopt: Trajopt) -> None:
    run = trajopt("solve", "qqqq")
    err = assert_stderr(run, 2, "unknown scenario 'qqqq'", "`trajopt scenarios`")
    assert "did you mean" not in err


# 6. the scenario table


def test_the_scenario_table_is_aligned(trajopt: Trajopt) -> None:
    run = trajopt("scenarios")
    assert run.code == 0 and run.err == ""
    header, *rest = run.out.splitlines()
    rows, sources = rest[0::2], rest[1::2]
    assert header.split() == ["NAME", "METHOD", "NODES", "TITLE"]
    for column in ("METHOD", "TITLE"):
        at = header.index(column)
        for row in rows:
            assert row[at - 2 : at] == "  " and row[at] != " ", (column, row)
    title = header.index("TITLE")
    assert all(s[:title].strip() == "" and s[title:].startswith("source: ") for s in sources)
    names = [row.split()[0] for row in rows]
    assert "rlv-max-terminal-velocity-active-nfz" in names and "rlv-min-heat-load" in names


# 7. files: broken JSON, missing, not an object, a directory, unreadable


def test_broken_json_names_the_file_line_and_column(trajopt: Trajopt, tmp_path: Path) -> None:
    (tmp_path / "bad.json").write_text('{\n  "vehicle": {\n    "mass_kg": ,\n', encoding="utf-8")
    run = trajopt("solve", "bad.json")
    assert_stderr(run, 2, "error: bad.json: invalid JSON at line 3 column 16: Expecting value")


@pytest.mark.parametrize("source", ["missing.json", "some/dir/problem", "./rlv-min-heat-load"])
def test_a_missing_file_that_looks_like_a_path_is_no_such_file(
    trajopt: Trajopt, source: str
) -> None:
    run = trajopt("solve", source)
    err = assert_stderr(run, 2, f"error: no such file: {source}")
    assert "scenario" not in err


def test_a_json_array_is_not_a_problem(trajopt: Trajopt, tmp_path: Path) -> None:
    (tmp_path / "list.json").write_text("[]", encoding="utf-8")
    run = trajopt("solve", "list.json")
    assert_stderr(run, 2, "list.json: a problem document must be a JSON object, not an array")


def test_a_directory_is_not_a_problem(trajopt: Trajopt, tmp_path: Path) -> None:
    (tmp_path / "cases").mkdir()
    assert_stderr(trajopt("solve", "cases"), 2, "cases is a directory, not a problem file")
    assert_stderr(trajopt("solve", str(tmp_path)), 2, "is a directory, not a problem file")


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads any file")
def test_an_unreadable_file_is_one_line(trajopt: Trajopt, tmp_path: Path) -> None:
    secret = tmp_path / "p.json"
    secret.write_text("{}", encoding="utf-8")
    secret.chmod(0)
    assert_stderr(trajopt("solve", "p.json"), 2, "cannot read p.json: permission denied")


def test_an_invalid_document_is_one_line_per_issue(trajopt: Trajopt, tmp_path: Path) -> None:
    (tmp_path / "p.json").write_text('{"vehicle": {}, "extra": 1}', encoding="utf-8")
    run = trajopt("solve", "p.json")
    assert run.code == 2 and "Traceback" not in run.err
    assert 2 <= len(run.err_lines) <= 11
    assert all(line.startswith("error: invalid problem p.json: ") for line in run.err_lines)
    assert "extra: unknown field" in run.err


# 8. every other path


def test_nodes_out_of_range_and_not_a_number(trajopt: Trajopt) -> None:
    run = trajopt("solve", "rlv-min-heat-load", "--nodes", "0")
    assert_stderr(run, 2, "method.nodes: Input should be greater than or equal to 3")
    run = trajopt("solve", "rlv-min-heat-load", "--nodes", "abc")
    assert_stderr(run, 2, "argument --nodes: not a whole number: 'abc'", "--help")


def test_an_unknown_method(trajopt: Trajopt) -> None:
    run = trajopt("solve", "rlv-min-heat-load", "--method", "newton")
    assert_stderr(run, 2, "invalid problem rlv-min-heat-load: method", "'energy-scp', 'foh-ptr'")


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (("bogus",), "invalid choice: 'bogus'"),
        ((), "the following arguments are required: COMMAND"),
        (("keys",), "the following arguments are required: ACTION"),
        (("solve",), "the following arguments are required: problem"),
        (("serve", "--port", "70000"), "port 70000 is outside 1..65535"),
        (("serve", "--port", "http"), "not a port number: 'http'"),
        (("worker", "--concurrency", "0"), "must be at least 1"),
        (("keys", "create"), "the following arguments are required: --client"),
    ],
)
def test_usage_errors_are_one_line(trajopt: Trajopt, args: tuple[str, ...], needle: str) -> None:
    assert_stderr(trajopt(*args), 2, needle, "--help`")


def test_help_still_works(trajopt: Trajopt) -> None:
    run = trajopt("--help")
    assert run.code == 0 and "Exit codes: 0 done" in run.out


def test_a_worker_without_a_broker_is_a_configuration_error(trajopt: Trajopt) -> None:
    assert_stderr(trajopt("worker"), 2, "error: no broker configured", "REDIS_URL")


def test_a_worker_with_a_visibility_timeout_too_short_is_refused(trajopt: Trajopt) -> None:
    run = trajopt(
        "worker", REDIS_URL=f"redis://127.0.0.1:{free_port()}/0", TRAJOPT_VISIBILITY_TIMEOUT_S="10"
    )
    assert_stderr(run, 2, "refusing to start: TRAJOPT_VISIBILITY_TIMEOUT_S=10")


def test_serve_on_a_port_in_use_is_refused(trajopt: Trajopt) -> None:
    import socket

    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        run = trajopt("serve", "--port", str(port))
    assert_stderr(run, 2, f"cannot listen on 127.0.0.1:{port}: Address already in use")


def test_serve_with_a_data_folder_that_cannot_exist(trajopt: Trajopt, tmp_path: Path) -> None:
    (tmp_path / "file").write_text("", encoding="utf-8")
    run = trajopt("serve", TRAJOPT_DATA_DIR=str(tmp_path / "file" / "data"))
    assert_stderr(run, 2, "TRAJOPT_DATA_DIR: cannot create", "Not a directory")


LOADING_NOTICE = "loading the solver's compiled kernels"
"""What trajopt solve says (without --quiet) when loading its kernels from the cache is slow."""


def test_ctrl_c_during_a_solve_is_exit_130_with_one_line(tmp_path: Path) -> None:
    def default_sigint() -> None:
        """Restore SIGINT's default: a shell may start children with it ignored."""
        signal.signal(signal.SIGINT, signal.SIG_DFL)

    process = subprocess.Popen(
        [sys.executable, "-m", "app.cli", "solve", "rlv-min-heat-load", "--nodes", "600"],
        cwd=tmp_path,
        env=_env(tmp_path),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=default_sigint,
    )
    try:
        assert process.stderr is not None
        first = process.stderr.readline()  # the first iteration: the solve is under way
        if first.startswith(LOADING_NOTICE):  # a slow load from numba's cache said first
            first = process.stderr.readline()
        assert first.startswith("iter "), first
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    after = [line for line in err.splitlines() if not line.startswith("iter ")]
    assert process.returncode == 130, err
    assert after == ["error: interrupted"] and out == ""


def test_a_breaking_solve_is_a_failed_result_without_numpy_warnings(trajopt: Trajopt) -> None:
    # 3 nodes: the iterates leave the physical range (a speed from an energy above the
    # potential's, or a step beyond the divergence bounds, depending on the weights)
    run = trajopt("solve", "rlv-min-heat-load", "--nodes", "3", "-q")
    assert run.code == 1 and run.out.startswith("status: failed")
    assert "reason: numerical_error" in run.out or "reason: diverged" in run.out, run.out
    assert "Warning" not in run.err and "Traceback" not in run.err, run.err
