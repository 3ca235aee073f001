"""Files and figures, imported on request (h5py, matplotlib): the one HDF5 layout of a run
and a study (:mod:`.store`), ParaView snapshot files (:mod:`.vtkhdf`) and every figure
(:mod:`.figures`)."""
