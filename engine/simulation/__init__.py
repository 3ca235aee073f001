"""What to simulate and running it: the scene (:mod:`.scene`), loose packings
(:mod:`.packing`), time-step limits (:mod:`.timestep`), :class:`Simulation` and its backends
(:mod:`.simulation`, :mod:`.backend`), snapshots of its particles and contacts
(:mod:`.snapshot`)."""
