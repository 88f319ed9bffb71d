"""Prometheus metrics read from the source of truth at scrape time.

Jobs by status and the solve-time histogram come from the database (so they cover every worker
process and survive restarts); the queue depth comes from the dispatcher; the plot renders of
this API process from its render pool.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator

from prometheus_client import CollectorRegistry
from prometheus_client.core import (
    CounterMetricFamily,
    GaugeMetricFamily,
    HistogramMetricFamily,
    Metric,
)
from prometheus_client.registry import Collector

from app.dispatch import Dispatcher
from app.failure_log import FailureLog
from app.render_pool import RenderPool
from app.storage import repository
from app.storage.session import Database

log = logging.getLogger(__name__)

SOLVE_TIME_BUCKETS_S: tuple[float, ...] = (
    0.1,
    0.25,
    0.5,
    1.0,
    2.5,
    5.0,
    10.0,
    30.0,
    60.0,
    120.0,
    300.0,
    600.0,
    1800.0,
    3600.0,
)


class ServiceCollector(Collector):
    """Yields ``trajopt_jobs``, ``trajopt_queue_depth`` and ``trajopt_job_solve_seconds``."""

    def __init__(self, database: Database, dispatcher: Dispatcher) -> None:
        self._database = database
        self._dispatcher = dispatcher
        self._failures = FailureLog(log, "metrics")

    def describe(self) -> list[Metric]:
        """Nothing up front, so registering does not query the database."""
        return []

    def collect(self) -> Iterator[Metric]:
        """Query the database and the queue and yield the metric families."""
        up = GaugeMetricFamily("trajopt_database_up", "1 if the job database answered the scrape")
        try:
            with self._database.reader() as session:
                counts = repository.count_by_status(session)
                histogram = repository.solve_time_histogram(session, SOLVE_TIME_BUCKETS_S)
        except Exception as exc:
            self._failures.failed(exc, "query the database", "trajopt_database_up is 0")
            up.add_metric([], 0)
            yield up
            return
        self._failures.succeeded("the database answers again")
        up.add_metric([], 1)
        yield up

        jobs = GaugeMetricFamily("trajopt_jobs", "Stored jobs by status", labels=["status"])
        for status, count in counts.items():
            jobs.add_metric([status], count)
        yield jobs

        depth = self._dispatcher.queue_depth()
        if depth is not None:
            yield GaugeMetricFamily(
                "trajopt_queue_depth", "Jobs waiting for a worker in the queue", value=depth
            )

        buckets = [(_le(b), c) for b, c in zip(histogram.bounds, histogram.cumulative, strict=True)]
        buckets.append(("+Inf", histogram.count))
        yield HistogramMetricFamily(
            "trajopt_job_solve_seconds",
            "Solver wall time of finished jobs",
            buckets=buckets,
            sum_value=histogram.total,
        )


def _le(bound: float) -> str:
    return repr(float(bound))


class RenderCollector(Collector):
    """Yields ``trajopt_plot_renders_total``, ``trajopt_plot_render_refusals_total`` and
    ``trajopt_plot_renders_waiting`` of this API process."""

    def __init__(self, renders: RenderPool) -> None:
        self._renders = renders

    def describe(self) -> list[Metric]:
        """Nothing up front (like :class:`ServiceCollector`)."""
        return []

    def collect(self) -> Iterator[Metric]:
        """The render pool's counts now."""
        renders = self._renders
        yield CounterMetricFamily(
            "trajopt_plot_renders", "Plots rendered by this API process", value=renders.rendered
        )
        yield CounterMetricFamily(
            "trajopt_plot_render_refusals",
            "Plot requests refused with too_many_renders by this API process",
            value=renders.refused,
        )
        yield GaugeMetricFamily(
            "trajopt_plot_renders_waiting",
            "Plots waiting for a render process of this API process",
            value=renders.waiting(),
        )


def build_registry(
    database: Database, dispatcher: Dispatcher, renders: RenderPool | None = None
) -> CollectorRegistry:
    """A registry holding only this service's collectors (no process-global state)."""
    registry = CollectorRegistry(auto_describe=False)
    registry.register(ServiceCollector(database, dispatcher))
    if renders is not None:
        registry.register(RenderCollector(renders))
    return registry
