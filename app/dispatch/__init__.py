"""How submitted jobs reach a worker: Celery over Redis, or a local process pool when no broker."""

from __future__ import annotations

from app.dispatch.base import Dispatcher
from app.settings import Settings


def make_dispatcher(settings: Settings) -> Dispatcher:
    """The Celery dispatcher when a broker URL is set, else the local process pool."""
    if settings.uses_broker:
        from app.dispatch.celery_dispatch import CeleryDispatcher

        return CeleryDispatcher(settings)
    from app.dispatch.local import LocalDispatcher

    return LocalDispatcher(settings)


__all__ = ["Dispatcher", "make_dispatcher"]
