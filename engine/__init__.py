"""demscale engine: a numba DEM engine for uniaxial tests of cohesive particle beds and
coarse-graining (scaling) studies. SI units throughout; numpy arrays in and out.

Public API (stable names)::

    BilinearAdhesive, EEPA, HertzMindlin, WallMaterial
                                                    contact-law parameter records
    Plane, Scene                                    what to simulate
    Simulation                                      run it
    critical_time_step                              time-step limits of a scene
    UniaxialTest, preset, run_uniaxial              the uniaxial test and its stages
    Checkpoint                                      resume a killed run where it was
    ScalingRule, StudySpec, run_study               scaling studies, errors and costs
    FileChannel                                     progress and stop of runs on other hosts
    NAMED_RULES, METRICS, DEFAULT_TOLERANCES        named rules, verdict metrics
    default_study                                   the study of the main job
    Snapshot, SnapshotWriter                        particles and contacts for ParaView
    ParameterError, StabilityError, InstabilityError
"""

from .channel import FileChannel
from .checkpoint import Checkpoint
from .errors import (
    InstabilityError,
    ParameterError,
    StabilityError,
    StopRequested,
    WallTimeExceeded,
)
from .kernels import FEATURES
from .materials import EEPA, BilinearAdhesive, HertzMindlin, WallMaterial
from .metrics import DEFAULT_TOLERANCES, METRICS
from .scene import Plane, Scene
from .simulation import Contacts, Simulation, StabilityWarning
from .snapshots import Snapshot, SnapshotWriter
from .stability import TimeStepLimit, critical_time_step
from .study import (
    NAMED_RULES,
    PlannedRun,
    RunFailed,
    RunResult,
    ScalingRule,
    StudyProgress,
    StudyResult,
    StudySpec,
    default_study,
    run_study,
)
from .uniaxial import (
    RESUMED,
    Progress,
    StageError,
    StageResult,
    UniaxialResult,
    UniaxialTest,
    preset,
    run_uniaxial,
)

__version__ = "0.1.0"

__all__ = [
    "DEFAULT_TOLERANCES",
    "EEPA",
    "FEATURES",
    "METRICS",
    "NAMED_RULES",
    "RESUMED",
    "BilinearAdhesive",
    "Checkpoint",
    "Contacts",
    "FileChannel",
    "HertzMindlin",
    "InstabilityError",
    "ParameterError",
    "Plane",
    "PlannedRun",
    "Progress",
    "RunFailed",
    "RunResult",
    "ScalingRule",
    "Scene",
    "Simulation",
    "Snapshot",
    "SnapshotWriter",
    "StabilityError",
    "StabilityWarning",
    "StageError",
    "StageResult",
    "StopRequested",
    "StudyProgress",
    "StudyResult",
    "StudySpec",
    "TimeStepLimit",
    "UniaxialResult",
    "UniaxialTest",
    "WallMaterial",
    "WallTimeExceeded",
    "critical_time_step",
    "default_study",
    "preset",
    "run_study",
    "run_uniaxial",
]
