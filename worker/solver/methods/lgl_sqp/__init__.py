"""Paper 004's evolutionary collocation: a GA or PSO global guess, then Legendre–Gauss–Lobatto
collocation of every phase solved by SQP (Wang, Leonard, Savvaris & Tsourdos)."""

from app.schemas.methods import LglSqpOptions
from worker.solver.methods.base import MethodInfo, Runner
from worker.solver.methods.lgl_sqp.support import NAME, OBJECTIVES, check_support

METHOD = MethodInfo(
    name=NAME,
    title="Evolutionary collocation: GA or PSO initial guess, LGL collocation of linked phases "
    "solved by SQP, propulsion and mass",
    paper="Wang, Leonard, Savvaris & Tsourdos, skip entry trajectory optimization with thrust by "
    "evolutionary collocation (paper 004)",
    features=(
        "phases linked by state continuity, each with its duration, end conditions, control "
        "bounds and path limits",
        "propulsion: thrust along the body axis, mass flow, first-order thrust lag",
        "angle of attack, bank and commanded thrust as controls",
        "global initial guess by a genetic algorithm or particle swarm (pymoo)",
        "Legendre-Gauss-Lobatto collocation in integral form on segments of every phase",
        "SQP: elastic Clarabel QP, convexified exact Hessian blocks, merit or filter line search",
        "path limits (heat rate with its alpha factor, dynamic pressure, load factor)",
        "exponential or US76 atmosphere, rotating or non-rotating planet",
    ),
    objectives=OBJECTIVES,
    options_type=LglSqpOptions,
    check=check_support,
    run=Runner("worker.solver.methods.lgl_sqp.method", LglSqpOptions),
    phases=True,
    propulsion=True,
)
