"""The compiled time step: the step template and its specialisation per scene
(:mod:`.specialise`), the state records it takes (:mod:`.state`), its thread team
(:mod:`.team`, on the atomics of :mod:`.atomics`) and the neighbour list (:mod:`.neighbour`)."""
