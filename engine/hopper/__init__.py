"""The simulated hopper discharge: parameters, scene, stages, measures (docs/HOPPER.md)."""
