"""Command-line options shared by the benchmarks that start the service stack."""

from __future__ import annotations

import argparse
import os
from pathlib import Path


def add_stack_arguments(parser: argparse.ArgumentParser, redis_db: int) -> None:
    """PostgreSQL and Redis URLs (from BENCH_* variables or loopback defaults) and --output."""
    parser.add_argument(
        "--postgres-url",
        default=os.environ.get("BENCH_POSTGRES_URL", "postgresql://postgres@127.0.0.1:5432/test"),
    )
    parser.add_argument(
        "--redis-url",
        default=os.environ.get("BENCH_REDIS_URL", f"redis://127.0.0.1:6379/{redis_db}"),
    )
    parser.add_argument("--output", type=Path, help="also write the figures as JSON")
