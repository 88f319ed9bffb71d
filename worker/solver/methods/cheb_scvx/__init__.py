"""Paper 001's Chebyshev pseudospectral SCvx with the lift vector as control, free final time,
no-fly zones and waypoints (Yu, Zhao & Yang)."""

from app.schemas.methods import ChebScvxOptions
from worker.solver.methods.base import MethodInfo, Runner
from worker.solver.methods.cheb_scvx.support import NAME, OBJECTIVES, check_support

METHOD = MethodInfo(
    name=NAME,
    title="Chebyshev pseudospectral SCvx with the lift vector as control, free final time",
    paper="Yu, Zhao & Yang, Convex Optimization of Entry Trajectory with Chebyshev Pseudospectral "
    "Method (International Journal of Aerospace Engineering, 2019; paper 001)",
    features=(
        "time as independent variable, free (or fixed) final time",
        "Chebyshev-Gauss-Lobatto collocation, one polynomial per segment between waypoints",
        "lift vector u = (lambda cos sigma, lambda sin sigma, lambda^2) as control, relaxed "
        "cone u1^2 + u2^2 <= u3 with the bank range as linear cuts",
        "parabolic-polar vehicles (normalized lift lambda in its range); any aerodynamic model "
        "with an optimized angle of attack, alpha derived from the lift share lambda = "
        "CL(alpha, M) / CL(alpha_max, M); or with a scheduled angle of attack (the lift "
        "vector's length the share of the schedule's lift flown, priced to 1)",
        "bank-rate limit at the points and between them",
        "spherical (rotating or not) or flat-Earth (paper 001 eq. 1) planet model",
        "path limits (heat rate, dynamic pressure, load factor) added where the reference nears "
        "them",
        "no-fly zones, also between the points",
        "waypoints in order, each at a segment joint with a free time of arrival",
        "terminal conditions fixed, range or free",
        "exponential or US76 atmosphere",
    ),
    objectives=OBJECTIVES,
    options_type=ChebScvxOptions,
    check=check_support,
    run=Runner("worker.solver.methods.cheb_scvx.method", ChebScvxOptions),
)
