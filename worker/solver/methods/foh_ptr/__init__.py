"""Paper 002's time-domain SCP with exact FOH discretization and an adaptive grid (Ma, Chen,
Wang & Zhang)."""

from app.schemas.methods import FohPtrOptions
from worker.solver.methods.base import MODEL_FEATURES, MethodInfo, Runner
from worker.solver.methods.foh_ptr.support import NAME, OBJECTIVES, check_support

METHOD = MethodInfo(
    name=NAME,
    title="Time-domain SCP with exact FOH discretization and adaptive grid (experimental: "
    "converges to local optima below the reference; see docs/methods/foh-ptr.md)",
    paper="Ma, Chen, Wang & Zhang, Real-Time Trajectory Planning for Hypersonic Entry Using "
    "Adaptive Non-Uniform Discretization and Convex Optimization (paper 002)",
    features=(
        "time as independent variable, fixed or free final time (intervals as time dilations)",
        "bank angle as a state, bank rate as the control (first-order hold)",
        "an optimized angle of attack (or a parabolic polar's normalized lift) as a second "
        "held state, its rate a second control",
        "inverse-free exact FOH discretization stitched to the propagated reference",
        "adaptive non-uniform grid (interval lengths as decision variables)",
        "path limits (heat rate, dynamic pressure, load factor), log-transformed",
        "no-fly zones",
        "bank magnitude and bank rate limits",
        *MODEL_FEATURES,
    ),
    objectives=OBJECTIVES,
    options_type=FohPtrOptions,
    check=check_support,
    run=Runner("worker.solver.methods.foh_ptr.method", FohPtrOptions),
    warm_kernels=True,
)
