"""Horner's rule for a polynomial and its slope: the one evaluation of every polynomial model.

Plain numpy arithmetic on a float or an array (complex-safe), also compiled into the numba
kernels (``register_jitable``), so aerodynamic, heat-rate and compiled forms share it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numba.extending import register_jitable

Value = Any  # a float or an array (real or complex)


@register_jitable
def horner(
    p: Sequence[float] | np.ndarray, first: int, count: int, x: Value
) -> tuple[Value, Value]:
    """p(x) = sum_k c_k x^k with c = p[first:first + count] (lowest order first) and p'(x).

    The recursion starts from the top coefficient with a zero slope (shaped like ``x``), which
    for finite x gives the very numbers of starting it from zero; ``count`` must be >= 1.
    """
    slope = x * 0.0 + 0.0
    value = slope + p[first + count - 1]
    for i in range(first + count - 2, first - 1, -1):
        slope = slope * x + value
        value = value * x + p[i]
    return value, slope
