"""Paper 003's SCP with angle of attack and bank as states on a multi-interval
Chebyshev-Gauss-Lobatto mesh, free final time (Liu, Cui, Du & Pu)."""

from app.schemas.methods import HpScpOptions
from worker.solver.methods.base import MODEL_FEATURES, MethodInfo, Runner
from worker.solver.methods.hp_scp.support import NAME, OBJECTIVES, check_support

METHOD = MethodInfo(
    name=NAME,
    title="Pseudospectral SCP with angle of attack and bank as states, free final time "
    "(experimental: not yet at its paper's optimum; see docs/methods/hp-scp.md)",
    paper="Liu, Cui, Du & Pu, Sequential Convex Programming for Reentry Trajectory "
    "Optimization Utilizing Modified hp-Adaptive Mesh Refinement and Variable Quadratic "
    "Penalty (paper 003)",
    features=(
        "time as independent variable, free final time",
        "angle of attack and bank as states, their rates as controls",
        "multi-interval Chebyshev-Gauss-Lobatto collocation (integral form), adaptive h-refinement",
        "attitude bounds and rate bounds on the whole interval polynomials (Bernstein hulls)",
        "path limits (heat rate with its alpha factor, dynamic pressure, load factor)",
        "no-fly zones",
        "angle of attack, bank and their rate limits (asymmetric bank range)",
        *MODEL_FEATURES[:3],  # terminal conditions, planet rotation, atmosphere
        "polynomial or tabulated aerodynamics in angle of attack",
    ),
    objectives=OBJECTIVES,
    options_type=HpScpOptions,
    check=check_support,
    run=Runner("worker.solver.methods.hp_scp.method", HpScpOptions),
)
