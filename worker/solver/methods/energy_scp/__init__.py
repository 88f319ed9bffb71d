"""Paper 000's energy-domain SCP with post-correction (Jung, Kim, Choi & Lee)."""

from app.schemas.methods import EnergyScpOptions
from worker.solver.methods.base import MODEL_FEATURES, MethodInfo, Runner
from worker.solver.methods.energy_scp.support import NAME, OBJECTIVES, check_support

METHOD = MethodInfo(
    name=NAME,
    title="Energy-domain SCP with post-correction",
    paper="Jung, Kim, Choi & Lee, Entry Vehicle Trajectory Optimization using Convex "
    "Programming and Post-correction Technique (paper 000)",
    features=(
        "energy as independent variable",
        "path limits (heat rate, dynamic pressure, load factor) as radius lower bounds",
        "bank magnitude limit",
        *MODEL_FEATURES,
    ),
    objectives=OBJECTIVES,
    options_type=EnergyScpOptions,
    check=check_support,
    run=Runner("worker.solver.methods.energy_scp.method", EnergyScpOptions),
    warm_kernels=True,  # the compiled deferred correction and the verification's rates
)
