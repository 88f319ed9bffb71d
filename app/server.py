"""``trajopt serve``: run the API with uvicorn in one process (jobs run elsewhere).

The listening socket is bound before anything else happens, so a second server on a port in use
fails at once, before it opens the database or touches a stored job.
"""

from __future__ import annotations

import contextlib
import errno
import logging
import socket

import uvicorn

from app.main import auth_banner
from app.settings import get_settings

LISTEN_BACKLOG = 2048
"""Pending connections the socket queues (uvicorn's default)."""


class BindError(Exception):
    """The API's address could not be listened on (in use, not local, not permitted)."""


def listen_socket(host: str, port: int) -> socket.socket:
    """A TCP socket bound to ``host:port`` and listening; raises :class:`BindError` naming why."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind((host, port))
        sock.listen(LISTEN_BACKLOG)
    except OSError as exc:
        sock.close()
        reason = exc.strerror or str(exc)
        if exc.errno == errno.EADDRINUSE:
            reason += " (another trajopt serve or another program listens there; use --port)"
        raise BindError(f"cannot listen on {host}:{port}: {reason}") from exc
    except OverflowError as exc:
        sock.close()
        raise BindError(f"cannot listen on {host}:{port}: {exc}") from exc
    return sock


def run_server(host: str | None = None, port: int | None = None) -> None:
    """Serve the API on ``host:port`` (defaults from settings) until interrupted.

    Raises :class:`BindError` before anything else when the address cannot be listened on.
    """
    settings = get_settings()
    host = host or settings.host
    port = port or settings.port
    sock = listen_socket(host, port)
    shown = "localhost" if host in ("0.0.0.0", "::") else host
    mode = (
        "Celery workers via the configured broker"
        if settings.uses_broker
        else "a local process pool (embedded mode; no broker)"
    )
    base = f"http://{shown}:{port}"
    print(f"trajopt API: {base}  (docs: {base}/docs, your jobs: {base}/ui/)", flush=True)
    print(f"jobs run on {mode}; database: {_safe_url(settings.effective_database_url)}", flush=True)
    print(auth_banner(settings), flush=True)
    config = uvicorn.Config(
        "app.main:create_app", factory=True, host=host, port=port, log_level="info"
    )
    _log_service_messages()
    with sock, contextlib.suppress(KeyboardInterrupt):  # Ctrl+C: uvicorn has shut down cleanly
        uvicorn.Server(config).run(sockets=[sock])


def _log_service_messages() -> None:
    """Show the service's own INFO messages (solver loaded, jobs re-queued) beside uvicorn's."""
    handler = logging.StreamHandler()
    handler.setFormatter(logging.Formatter("%(levelname)s:     %(message)s"))
    for name in ("app", "worker"):
        logger = logging.getLogger(name)
        logger.setLevel(logging.INFO)
        logger.addHandler(handler)
        logger.propagate = False


def _safe_url(url: str) -> str:
    from sqlalchemy import make_url

    return make_url(url).render_as_string(hide_password=True)
