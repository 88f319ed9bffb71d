"""The docker compose deployment, checked without a Docker engine: services, health checks,
start-up order, ports and configuration variables."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest
import yaml

from app.settings import Settings

DOCKER = Path(__file__).resolve().parents[2] / "docker"
DEFAULT_RE = re.compile(r"^\$\{(?P<name>[A-Z0-9_]+)(:-(?P<default>[^}]*)|:\?[^}]*)?\}$")


@pytest.fixture(scope="module")
def compose() -> dict[str, Any]:
    loaded: dict[str, Any] = yaml.safe_load((DOCKER / "compose.yml").read_text())
    return loaded


def _services(compose: dict[str, Any]) -> dict[str, Any]:
    services: dict[str, Any] = compose["services"]
    return services


def _settings_env_names() -> set[str]:
    names = {f"TRAJOPT_{name.upper()}" for name in Settings.model_fields}
    return names | {"DATABASE_URL", "REDIS_URL"}


def test_the_four_services_with_health_checks(compose: dict[str, Any]) -> None:
    services = _services(compose)
    assert set(services) == {"api", "worker", "redis", "postgres"}
    for name, service in services.items():
        check = service.get("healthcheck")
        assert check and check.get("test"), f"{name} has no health check"
        assert check["test"][0] in ("CMD", "CMD-SHELL"), name
    assert any("/readyz" in part for part in services["api"]["healthcheck"]["test"])
    assert "redis-cli" in services["redis"]["healthcheck"]["test"]
    assert "pg_isready" in " ".join(services["postgres"]["healthcheck"]["test"])
    assert "inspect ping" in " ".join(services["worker"]["healthcheck"]["test"])


def test_start_up_order_waits_for_healthy_dependencies(compose: dict[str, Any]) -> None:
    services = _services(compose)
    for name in ("api", "worker"):
        depends = services[name]["depends_on"]
        for dependency in ("postgres", "redis"):
            assert depends[dependency]["condition"] == "service_healthy", (name, dependency)
    assert services["worker"]["depends_on"]["api"]["condition"] == "service_healthy"


def test_api_port_and_worker_replicas(compose: dict[str, Any]) -> None:
    services = _services(compose)
    published = services["api"]["ports"]
    assert len(published) == 1
    assert published[0].endswith(":8000")
    assert "8000" in services["api"]["command"]
    replicas = DEFAULT_RE.match(str(services["worker"]["deploy"]["replicas"]))
    assert replicas is not None
    assert int(replicas["default"]) >= 2
    for name in ("redis", "postgres"):
        assert "ports" not in services[name], f"{name} must stay on the internal network"


def test_redis_is_durable_and_never_evicts(compose: dict[str, Any]) -> None:
    command = _services(compose)["redis"]["command"]
    joined = " ".join(str(c) for c in command)
    assert "--appendonly yes" in joined
    assert "--maxmemory-policy noeviction" in joined


def test_configuration_is_environment_with_no_default_secrets(compose: dict[str, Any]) -> None:
    services = _services(compose)
    known = _settings_env_names()
    for name in ("api", "worker"):
        env = services[name]["environment"]
        assert env["REDIS_URL"].startswith("redis://redis:6379/")
        assert "@postgres:5432/" in env["DATABASE_URL"]
        assert "${POSTGRES_PASSWORD:?" in env["DATABASE_URL"]
        unknown = {k for k in env if k not in known}
        assert not unknown, f"{name} sets variables the service does not read: {unknown}"
    password = services["postgres"]["environment"]["POSTGRES_PASSWORD"]
    assert password.startswith("${POSTGRES_PASSWORD:?"), "the password must have no default"
    text = (DOCKER / "compose.yml").read_text()
    assert not re.search(r"PASSWORD[^:\n]*:-", text), "a password has a default value"


def test_the_visibility_timeout_default_exceeds_the_hard_limit(compose: dict[str, Any]) -> None:
    env = _services(compose)["worker"]["environment"]

    def default(key: str) -> float:
        match = DEFAULT_RE.match(env[key])
        assert match is not None
        return float(match["default"])

    settings = Settings(
        max_time_limit_s=default("TRAJOPT_MAX_TIME_LIMIT_S"),
        visibility_timeout_s=default("TRAJOPT_VISIBILITY_TIMEOUT_S"),
    )
    assert settings.visibility_timeout_s > settings.max_hard_limit_s


def test_images_are_built_from_the_project(compose: dict[str, Any]) -> None:
    services = _services(compose)
    build = services["api"]["build"]
    assert build["dockerfile"] == "docker/Dockerfile"
    assert (DOCKER / build["context"] / "pyproject.toml").is_file()
    assert services["worker"]["image"] == services["api"]["image"]
    # every service running the project's image builds it and never pulls it (`up --build`
    # must not ask a registry for trajopt:latest)
    for name in ("api", "worker"):
        assert services[name]["build"] == build, name
        assert services[name]["pull_policy"] == "build", name
    dockerfile = (DOCKER / "Dockerfile").read_text()
    assert "COPY pyproject.toml" in dockerfile
    assert 'ENTRYPOINT ["trajopt"]' in dockerfile
    assert re.search(r"^USER (?!root)", dockerfile, re.MULTILINE)


def test_the_image_installs_the_pinned_numerical_libraries() -> None:
    """The image installs with constraints.txt, as the tests do: production runs the versions
    the golden outputs are checked against, and the file reaches the build context."""
    dockerfile = (DOCKER / "Dockerfile").read_text()
    installs = re.findall(r"pip install ([^\\\n&]*)", dockerfile)
    assert installs, "the Dockerfile installs nothing"
    assert all("-c constraints.txt" in line for line in installs), installs
    copied = re.search(r"^COPY (.*) \./$", dockerfile, re.MULTILINE)
    assert copied is not None and "constraints.txt" in copied.group(1).split()
    ignore = (DOCKER / "Dockerfile.dockerignore").read_text().splitlines()
    assert "!constraints.txt" in ignore
    pins = (DOCKER.parent / "constraints.txt").read_text()
    for library in ("numpy", "scipy", "clarabel", "piqp", "numba", "cvxpy", "pymoo", "ussa1976"):
        assert re.search(rf"^{library}==", pins, re.MULTILINE), library


def test_the_deployment_requires_api_keys_and_a_secret(compose: dict[str, Any]) -> None:
    for name in ("api", "worker"):
        env = _services(compose)[name]["environment"]
        assert env["TRAJOPT_AUTH_MODE"] == "api-keys"
        assert env["TRAJOPT_API_KEY_SECRET"].startswith("${TRAJOPT_API_KEY_SECRET:?")
        assert env["TRAJOPT_CORS_ORIGINS"] == "${TRAJOPT_CORS_ORIGINS:-}"  # closed by default
    text = (DOCKER / "compose.yml").read_text()
    assert not re.search(r"SECRET[^:\n]*:-", text), "a secret has a default value"
