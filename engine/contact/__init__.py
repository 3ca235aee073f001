"""Contact laws: each law's parameter record with what the engine asks of it, the scalar
force kernels, the one contact composition shared by particle pairs and walls, and the
time-step formulas the laws use."""
