"""Where a value (numbers, arrays, dicts and lists of them) holds NaN or infinity: one test for
the driver's divergence check and the result's last guard, so neither reports a non-finite
number as an answer."""

from __future__ import annotations

import math
from typing import Any

import numpy as np


def non_finite_entries(value: Any, path: str = "") -> list[str]:
    """Where ``value`` (numbers, arrays, dicts and lists of them) holds NaN or infinity: each
    entry's dotted path and how many values there are non-finite (a list counts once)."""
    if isinstance(value, bool | int | str) or value is None:
        return []
    if isinstance(value, float):
        return [] if math.isfinite(value) else [path]
    if isinstance(value, dict):
        inner = ((f"{path}.{k}".lstrip("."), v) for k, v in value.items())
        return [e for where, v in inner for e in non_finite_entries(v, where)]
    if isinstance(value, np.ndarray) and value.dtype.kind == "f":  # numbers only: vectorized
        bad = int(np.count_nonzero(~np.isfinite(value)))
        return [f"{path} ({bad} of {value.size} values)"] if bad else []
    if isinstance(value, list | tuple | np.ndarray):
        flat = np.asarray(value, dtype=object).ravel()
        numbers = [v for v in flat if isinstance(v, float | np.floating)]
        bad = sum(1 for v in numbers if not math.isfinite(float(v)))
        nested = [e for v in flat if isinstance(v, dict) for e in non_finite_entries(v, path)]
        return ([f"{path} ({bad} of {flat.size} values)"] if bad else []) + nested
    if isinstance(value, np.floating):
        return [] if math.isfinite(float(value)) else [path]
    return []
