"""Conic (SOCP) subproblem layer of the SCP solver: problem data, backends and their statuses.

Each SCP iteration hands one ``ConeProblem`` to a ``ConicBackend`` and gets a ``ConicSolution``.
"""

from worker.solver.conic.base import CVXPY_SOLVERS, ConicBackend, ConicSolution
from worker.solver.conic.clarabel_direct import ClarabelBackend
from worker.solver.conic.cvxpy_backend import CvxpyBackend
from worker.solver.conic.fallback import FallbackBackend
from worker.solver.conic.piqp_direct import PiqpBackend
from worker.solver.conic.problem import ConeProblem, ConeSpec, SparseAssembler, same_pattern
from worker.solver.conic.registry import KNOWN_BACKENDS, make_backend
from worker.solver.conic.status import ConicStatus, map_clarabel_status, map_cvxpy_status

__all__ = [
    "CVXPY_SOLVERS",
    "KNOWN_BACKENDS",
    "ClarabelBackend",
    "ConeProblem",
    "ConeSpec",
    "ConicBackend",
    "ConicSolution",
    "ConicStatus",
    "CvxpyBackend",
    "FallbackBackend",
    "PiqpBackend",
    "SparseAssembler",
    "make_backend",
    "map_clarabel_status",
    "map_cvxpy_status",
    "same_pattern",
]
