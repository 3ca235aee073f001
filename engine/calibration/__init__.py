"""From laboratory data to a contact law (docs/CALIBRATION.md): the targets a powder's
uniaxial-tester data give (:mod:`engine.calibration.targets`)."""

from .targets import CompressionPoint, LabTargets, StrengthPoint

__all__ = ["CompressionPoint", "LabTargets", "StrengthPoint"]
