"""The public problem contract: pydantic models of the problem document and its error report.

Imports neither FastAPI nor Celery, so the solver core and the command line can use it too.
"""

from app.schemas.aerodynamics import (
    Aerodynamics,
    ParabolicPolarAerodynamics,
    PolynomialAerodynamics,
    TableAerodynamics,
)
from app.schemas.base import StrictModel
from app.schemas.constraints import (
    ControlLimits,
    DynamicPressureLimit,
    HeatRateLimit,
    LoadFactorLimit,
    PathConstraints,
)
from app.schemas.errors import FieldIssue, dotted_path, issues_from_validation_error
from app.schemas.examples import RLV_MIN_HEAT_LOAD
from app.schemas.limits import (
    MAX_ITERATIONS,
    MAX_NO_FLY_ZONES,
    MAX_NODES,
    MAX_OBJECTIVE_TERMS,
    MAX_PHASES,
    MAX_POLYNOMIAL_COEFFICIENTS,
    MAX_TABLE_POINTS,
    MAX_TIME_LIMIT_S,
    MAX_WAYPOINTS,
)
from app.schemas.methods import (
    AUTO,
    DEFAULT_METHOD,
    METHOD_NAMES,
    METHOD_OPTIONS,
    AutoOptions,
    EnergyScpOptions,
    EnergyStopTolerance,
    MethodSpec,
)
from app.schemas.objective import Objective, ObjectiveName, ObjectiveTerm
from app.schemas.phases import AngleBounds, DurationBounds, Phase
from app.schemas.planet import Atmosphere, ExponentialAtmosphere, Planet, US76Atmosphere
from app.schemas.problem import SCHEMA_VERSION, ProblemDocument
from app.schemas.propulsion import STANDARD_GRAVITY_M_S2, Propulsion
from app.schemas.regions import NoFlyZone, Waypoint
from app.schemas.state import (
    EnergyBounds,
    FinalTime,
    FixedFinalTime,
    FreeFinalTime,
    InitialState,
)
from app.schemas.terminal import (
    FixedSpec,
    FreeSpec,
    RangeSpec,
    SoftSpec,
    TerminalConditions,
    TerminalSpec,
)
from app.schemas.vehicle import (
    AngleOfAttack,
    ConstantAngleOfAttack,
    OptimizedAngleOfAttack,
    TableAngleOfAttack,
    Vehicle,
    VelocityScheduleAngleOfAttack,
)

__all__ = [
    "AUTO",
    "DEFAULT_METHOD",
    "MAX_ITERATIONS",
    "MAX_NODES",
    "MAX_NO_FLY_ZONES",
    "MAX_OBJECTIVE_TERMS",
    "MAX_PHASES",
    "MAX_POLYNOMIAL_COEFFICIENTS",
    "MAX_TABLE_POINTS",
    "MAX_TIME_LIMIT_S",
    "MAX_WAYPOINTS",
    "METHOD_NAMES",
    "METHOD_OPTIONS",
    "RLV_MIN_HEAT_LOAD",
    "SCHEMA_VERSION",
    "STANDARD_GRAVITY_M_S2",
    "Aerodynamics",
    "AngleBounds",
    "AngleOfAttack",
    "Atmosphere",
    "AutoOptions",
    "ConstantAngleOfAttack",
    "ControlLimits",
    "DurationBounds",
    "DynamicPressureLimit",
    "EnergyBounds",
    "EnergyScpOptions",
    "EnergyStopTolerance",
    "ExponentialAtmosphere",
    "FieldIssue",
    "FinalTime",
    "FixedFinalTime",
    "FixedSpec",
    "FreeFinalTime",
    "FreeSpec",
    "HeatRateLimit",
    "InitialState",
    "LoadFactorLimit",
    "MethodSpec",
    "NoFlyZone",
    "Objective",
    "ObjectiveName",
    "ObjectiveTerm",
    "OptimizedAngleOfAttack",
    "ParabolicPolarAerodynamics",
    "PathConstraints",
    "Phase",
    "Planet",
    "PolynomialAerodynamics",
    "ProblemDocument",
    "Propulsion",
    "RangeSpec",
    "SoftSpec",
    "StrictModel",
    "TableAerodynamics",
    "TableAngleOfAttack",
    "TerminalConditions",
    "TerminalSpec",
    "US76Atmosphere",
    "Vehicle",
    "VelocityScheduleAngleOfAttack",
    "Waypoint",
    "dotted_path",
    "issues_from_validation_error",
]
