"""demscale engine: a numba DEM engine for uniaxial tests of cohesive particle beds and
coarse-graining (scaling) studies. SI units throughout; numpy arrays in and out.

Public API (stable names)::

    BilinearAdhesive, HertzMindlin, WallMaterial    contact-law parameter records
    Plane, Scene                                    what to simulate
    Simulation                                      run it
    critical_time_step                              time-step limits of a scene
    ParameterError, StabilityError, InstabilityError
"""

from .errors import InstabilityError, ParameterError, StabilityError, StopRequested
from .kernels import FEATURES
from .materials import BilinearAdhesive, HertzMindlin, WallMaterial
from .scene import Plane, Scene
from .simulation import Contacts, Simulation, StabilityWarning
from .stability import TimeStepLimit, critical_time_step

__version__ = "0.1.0"

__all__ = [
    "FEATURES",
    "BilinearAdhesive",
    "Contacts",
    "HertzMindlin",
    "InstabilityError",
    "ParameterError",
    "Plane",
    "Scene",
    "Simulation",
    "StabilityError",
    "StabilityWarning",
    "StopRequested",
    "TimeStepLimit",
    "WallMaterial",
    "critical_time_step",
]
