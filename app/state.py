"""What the running API holds: settings, database, dispatcher, event waker, metrics registry and
rate limiter, event streams, plot renders, body lanes."""

from __future__ import annotations

from dataclasses import dataclass, field

from prometheus_client import CollectorRegistry

from app.body_lanes import BodyLanes
from app.dispatch import Dispatcher
from app.events import Waker
from app.ratelimit import RateLimiter
from app.render_pool import RenderPool
from app.settings import Settings
from app.storage.session import Database
from app.stream_hub import StreamHub


@dataclass
class ServiceState:
    """The long-lived objects of one API process, stored on ``app.state.service``."""

    settings: Settings
    database: Database
    dispatcher: Dispatcher
    waker: Waker
    registry: CollectorRegistry
    rate_limiter: RateLimiter
    streams: StreamHub
    """Caps and feeds the process's event streams (one shared watcher of their jobs)."""
    renders: RenderPool
    """Renders plots in other processes, each client's one at a time, clients in turn."""
    body_lanes: BodyLanes = field(default_factory=BodyLanes)
    """Reads and decodes each client's large request bodies one at a time."""
