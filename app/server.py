"""``trajopt serve``: run the API with uvicorn in one process (jobs run elsewhere)."""

from __future__ import annotations

import uvicorn

from app.main import auth_banner
from app.settings import get_settings


def run_server(host: str | None = None, port: int | None = None) -> None:
    """Serve the API on ``host:port`` (defaults from settings) until interrupted."""
    settings = get_settings()
    host = host or settings.host
    port = port or settings.port
    shown = "localhost" if host in ("0.0.0.0", "::") else host
    mode = (
        "Celery workers via the configured broker"
        if settings.uses_broker
        else "a local process pool (embedded mode; no broker)"
    )
    print(f"trajopt API: http://{shown}:{port}  (docs: http://{shown}:{port}/docs)", flush=True)
    print(f"jobs run on {mode}; database: {_safe_url(settings.effective_database_url)}", flush=True)
    print(auth_banner(settings), flush=True)
    uvicorn.run("app.main:create_app", factory=True, host=host, port=port, log_level="info")


def _safe_url(url: str) -> str:
    from sqlalchemy import make_url

    return make_url(url).render_as_string(hide_password=True)
