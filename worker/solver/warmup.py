"""The warm-up of every compiled kernel of the solver, so no job's time limit pays for numba.

It sits above every module that owns kernels (the model sweeps, the scalar integrator's rates,
the path rows, the FOH Hessian) and asks each to compile on a tiny case; ``python -m
worker.solver.warmup`` fills numba's on-disk cache (CI, the Docker image, the first start).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import numpy as np

from worker.solver.constraints import path_compiled
from worker.solver.models import bank_state_sweeps, flown_rates, scalar_rates
from worker.solver.transcription import energy_defect_compiled, foh_hessian

_warmed = False

NOTICE_AFTER_S = 1.0
"""Loading from numba's cache takes well under this; a warm-up still running then is compiling."""


def is_warm() -> bool:
    """Whether this process has loaded (or compiled) the kernels already."""
    return _warmed


def warm_up(notice: Callable[[], None] | None = None) -> float:
    """Compile every kernel (or load it from numba's on-disk cache) on a tiny case; seconds taken.

    The first compilation on a machine takes about 20 s; afterwards loading takes well under one.
    Worker processes call this before taking jobs, so a job's time limit never pays for it; once
    the kernels are loaded in this process it returns at once. ``notice`` is called (from a
    helper thread) if the warm-up is still running after ``NOTICE_AFTER_S``: it is compiling, and
    a caller can say why it waits.
    """
    if _warmed:
        return 0.0
    timer = None
    if notice is not None:
        timer = threading.Timer(NOTICE_AFTER_S, notice)
        timer.daemon = True
        timer.start()
    try:
        return _load_kernels()
    finally:
        if timer is not None:
            timer.cancel()


def _load_kernels() -> float:
    """Run each kernel-owning module's warm-up once; seconds taken."""
    global _warmed
    start = time.perf_counter()
    head = [6.378e6, 7.9e3, 1.2e4, 1.225, 7.2e3, 0.06, 1.0, 40.0, 4.57e3, 1.8e-6, 1.0, 2.0, 2.0]
    params = np.array([*head, 0.0, 0.02, 0.08, 0.9])  # CL and CD(CL), two coefficients each
    bank_state_sweeps.warm_up(params)
    scalar_rates.time_rates(np.array([1.015, 0.0, 0.0, 0.9, 0.0, 0.0]), 1.0, 0.0, 0.1, 0.1, 0.06)
    foh_hessian.warm_up(params)
    flown_rates.warm_up(params)
    energy_defect_compiled.warm_up(params)
    path_compiled.warm_up(params)
    _warmed = True
    return time.perf_counter() - start


if __name__ == "__main__":
    print(f"compiled kernels ready in {warm_up():.1f} s")
