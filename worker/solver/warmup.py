"""The warm-up of every compiled kernel of the solver, so no job's time limit pays for numba.

It sits above every module that owns kernels (the model sweeps, the scalar integrator's rates,
the path rows, the FOH Hessian) and asks each to compile on a tiny case; ``python -m
worker.solver.warmup`` fills numba's on-disk cache (CI, the Docker image, the first start).
Whether the cache already holds them is read from numba's cache index, so a caller can say
"compiling" only when it compiles.
"""

from __future__ import annotations

import argparse
import sys
import threading
import time
from collections.abc import Callable
from typing import Literal

import numpy as np
from numba.core.caching import NullCache
from numba.core.dispatcher import Dispatcher
from numba.core.registry import cpu_target

from worker.solver.constraints import path_compiled
from worker.solver.models import bank_state_sweeps, flown_rates, scalar_rates
from worker.solver.transcription import energy_defect_compiled, foh_hessian

_warmed = False

KernelWait = Literal["compiling", "loading"]
"""What a warm-up does: compile the kernels (numba's cache lacks them) or load them from it."""

NOTICE_AFTER_S = 1.0
"""A load from numba's cache still running after this is worth a word (a machine under load)."""


def is_warm() -> bool:
    """Whether this process has loaded (or compiled) the kernels already."""
    return _warmed


def _kernels() -> list[Dispatcher]:
    """Every cached numba kernel of the solver's modules imported so far (this module imports
    all that own one)."""
    found: dict[int, Dispatcher] = {}
    for name, module in list(sys.modules.items()):
        if name.startswith("worker.solver.") and module is not None:
            for value in vars(module).values():
                cache = getattr(value, "_cache", None) if isinstance(value, Dispatcher) else None
                if cache is not None and not isinstance(cache, NullCache):
                    found[id(value)] = value
    return list(found.values())


def _in_cache(kernel: Dispatcher, target: tuple[object, ...]) -> bool:
    """Whether numba's on-disk cache index of ``kernel`` is fresh (its source unchanged) and holds
    code compiled for this processor."""
    try:
        index = getattr(kernel, "_cache")._cache_file._load_index()  # noqa: B009 (numba's own)
    except Exception:  # an unreadable index is recompiled by numba: say so
        return False
    return any(isinstance(key, tuple) and key[1] == target for key in index)


def kernels_cached() -> bool:
    """Whether every kernel loads from numba's on-disk cache (no compilation needed): its index
    exists, matches the kernel's source and holds this processor's code. Reads the index files
    only (a few milliseconds)."""
    target = cpu_target.target_context.codegen().magic_tuple()
    kernels = _kernels()
    return bool(kernels) and all(_in_cache(kernel, target) for kernel in kernels)


def warm_up(notice: Callable[[KernelWait], None] | None = None) -> float:
    """Compile every kernel (or load it from numba's on-disk cache) on a tiny case; seconds taken.

    The first compilation on a machine takes ``worker.solver.FIRST_COMPILE``; afterwards loading
    takes well under a second. Worker processes call this before taking jobs, so a job's time
    limit never pays for it; once the kernels are loaded in this process it returns at once.
    ``notice`` hears why the caller waits: ``"compiling"`` at once when numba's cache lacks the
    kernels, ``"loading"`` (from a helper thread) when a load from the cache is still running
    after NOTICE_AFTER_S.
    """
    if _warmed:
        return 0.0
    timer = None
    if notice is not None:
        if kernels_cached():
            timer = threading.Timer(NOTICE_AFTER_S, notice, args=("loading",))
            timer.daemon = True
            timer.start()
        else:
            notice("compiling")
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


def parser() -> argparse.ArgumentParser:
    """main()'s argument parser (no arguments, ``--help``), so a wrong argument is an error."""
    return argparse.ArgumentParser(
        prog="python -m worker.solver.warmup",
        description="Compile the solver's kernels into numba's cache, or load them from it.",
    )


def main() -> None:
    """``python -m worker.solver.warmup``: fill numba's cache, saying whether it compiled."""
    parser().parse_args()
    done = "loaded from numba's cache" if kernels_cached() else "compiled into numba's cache"
    print(f"solver kernels {done} in {warm_up():.1f} s", flush=True)


if __name__ == "__main__":
    main()
