"""The simulated Jenike-type shear test: parameters, stages, yield locus (docs/SHEAR.md)."""
