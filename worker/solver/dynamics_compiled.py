"""Former home of the compiled bank-state kernels: re-exports them from ``worker.solver.models``.

The kernels live in ``models.bank_state_compiled`` (parameters, point rates, RK4 propagation)
and ``models.bank_state_sweeps`` (FOH maps, adjoint Hessians, warm-up); this module keeps the
old import paths and ``python -m worker.solver.dynamics_compiled`` working until callers move.
"""

from __future__ import annotations

from worker.solver.models.bank_state_compiled import (
    AUGMENTED_COLUMNS as NAUG,
)
from worker.solver.models.bank_state_compiled import (
    N as NZ,
)
from worker.solver.models.bank_state_compiled import (
    aero_terms,
    chain_kernel,
    compiled_parameters,
    float_arrays,
    propagate_kernel,
)
from worker.solver.models.bank_state_sweeps import (
    interval_maps_kernel,
    is_warm,
    lagrangian_hessian_kernel,
    warm_up,
)

__all__ = [
    "NAUG",
    "NZ",
    "aero_terms",
    "chain_kernel",
    "compiled_parameters",
    "float_arrays",
    "interval_maps_kernel",
    "is_warm",
    "lagrangian_hessian_kernel",
    "propagate_kernel",
    "warm_up",
]

if __name__ == "__main__":
    print(f"compiled dynamics ready in {warm_up():.1f} s")
