"""demscale engine: a numba DEM engine for uniaxial tests of cohesive particle beds and
coarse-graining (scaling) studies. SI units throughout; numpy arrays in and out.

Public API (stable names)::

    BilinearAdhesive, EEPA, HertzMindlin, WallMaterial
                                                    contact-law parameter records
    Plane, Scene                                    what to simulate
    Mesh                                            a wall of finite extent (triangles, STL)
    Simulation                                      run it
    ParkingLattice                                  sites of parked particles (a sink)
    critical_time_step                              time-step limits of a scene
    UniaxialTest, preset, run_uniaxial              the uniaxial test and its stages
    ShearTest, run_shear, ShearResult               the Jenike-type shear test (docs/SHEAR.md)
    HopperTest, run_hopper, HopperResult            the hopper discharge (docs/HOPPER.md)
    SEED_PROTOCOL                                   the seed's protocol (preset protocol="seed")
    Checkpoint                                      resume a killed run where it was
    ScalingRule, StudySpec, run_study               scaling studies, errors and costs
    plan, StudyPlan                                 a study's runs, planned once
    FileChannel                                     progress and stop of runs on other hosts
    NAMED_RULES, METRICS, DEFAULT_TOLERANCES        named rules, verdict metrics
    default_study                                   the study of the main job
    Snapshot, SnapshotWriter                        particles and contacts for ParaView
    ParameterError, StabilityError, InstabilityError
"""

from .calibration import Calibration, LabTargets, calibrate
from .contact.bilinear import BilinearAdhesive
from .contact.eepa import EEPA
from .contact.hertz import HertzMindlin
from .contact.wall import WallMaterial
from .core.errors import (
    InstabilityError,
    ParameterError,
    StabilityError,
    StopRequested,
    WallTimeExceeded,
)
from .core.similarity import similar
from .hopper.driver import run_hopper
from .hopper.results import HopperResult
from .hopper.spec import HopperTest
from .io.vtkhdf import SnapshotWriter
from .kernel.specialise import FEATURES
from .process import Process, ProcessPlan, plan_process
from .shear.driver import run_shear
from .shear.results import ShearResult
from .shear.spec import ShearTest
from .simulation.mesh import Mesh
from .simulation.parking import ParkingLattice
from .simulation.scene import Plane, Scene
from .simulation.simulation import Contacts, MeshContacts, Simulation, StabilityWarning
from .simulation.snapshot import Snapshot
from .simulation.timestep import TimeStepLimit, critical_time_step
from .study.channel import FileChannel
from .study.metrics import DEFAULT_TOLERANCES, METRICS
from .study.plan import PlannedRun, StudyPlan, plan
from .study.results import RunFailed, RunResult, StudyResult
from .study.run import RunOptions, StudyProgress, run_study
from .study.spec import NAMED_RULES, ScalingRule, StudySpec, default_study
from .uniaxial.checkpoint import Checkpoint
from .uniaxial.driver import StageError, run_uniaxial
from .uniaxial.flow import FlowFunction, flow_function
from .uniaxial.results import RESUMED, Progress, StageResult, UniaxialResult
from .uniaxial.spec import SEED_PROTOCOL, UniaxialTest, preset

__version__ = "0.1.0"

__all__ = [
    "DEFAULT_TOLERANCES",
    "EEPA",
    "FEATURES",
    "METRICS",
    "NAMED_RULES",
    "RESUMED",
    "SEED_PROTOCOL",
    "BilinearAdhesive",
    "Calibration",
    "Checkpoint",
    "Contacts",
    "FileChannel",
    "FlowFunction",
    "HertzMindlin",
    "HopperResult",
    "HopperTest",
    "InstabilityError",
    "LabTargets",
    "Mesh",
    "MeshContacts",
    "ParameterError",
    "ParkingLattice",
    "Plane",
    "PlannedRun",
    "Process",
    "ProcessPlan",
    "Progress",
    "RunFailed",
    "RunOptions",
    "RunResult",
    "ScalingRule",
    "Scene",
    "ShearResult",
    "ShearTest",
    "Simulation",
    "Snapshot",
    "SnapshotWriter",
    "StabilityError",
    "StabilityWarning",
    "StageError",
    "StageResult",
    "StopRequested",
    "StudyPlan",
    "StudyProgress",
    "StudyResult",
    "StudySpec",
    "TimeStepLimit",
    "UniaxialResult",
    "UniaxialTest",
    "WallMaterial",
    "WallTimeExceeded",
    "calibrate",
    "critical_time_step",
    "default_study",
    "flow_function",
    "plan",
    "plan_process",
    "preset",
    "run_hopper",
    "run_shear",
    "run_study",
    "run_uniaxial",
    "similar",
]
