"""From laboratory data to a contact law (docs/CALIBRATION.md): the targets a powder's
uniaxial-tester data give (:mod:`engine.calibration.targets`), the calibration that finds
the law's parameters with a posterior (:mod:`engine.calibration.calibrate`, on Gaussian-process
emulators: :mod:`engine.calibration.gp`)."""

from .calibrate import CALIBRATED, Calibration, calibrate, calibration_runs
from .targets import CompressionPoint, LabTargets, StrengthPoint

__all__ = [
    "CALIBRATED",
    "Calibration",
    "CompressionPoint",
    "LabTargets",
    "StrengthPoint",
    "calibrate",
    "calibration_runs",
]
