"""From laboratory data to a contact law (docs/CALIBRATION.md): the targets a powder's
uniaxial-tester data and a shear tester's yield loci give
(:mod:`engine.calibration.targets`), the calibration that finds the law's parameters with a
posterior (:mod:`engine.calibration.calibrate`, on Gaussian-process emulators:
:mod:`engine.calibration.gp`), and the shear side of its forward model, a shear test per
yield locus (:mod:`engine.calibration.forward`)."""

from .calibrate import CALIBRATED, Calibration, calibrate, calibration_runs
from .targets import CompressionPoint, LabTargets, LocusPoint, ShearLocus, StrengthPoint

__all__ = [
    "CALIBRATED",
    "Calibration",
    "CompressionPoint",
    "LabTargets",
    "LocusPoint",
    "ShearLocus",
    "StrengthPoint",
    "calibrate",
    "calibration_runs",
]
