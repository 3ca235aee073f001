"""The REST endpoints: studies (submit, list, status, cancel, delete) and results (summary,
curves, plots, HDF5 file)."""
