"""The uniaxial test: its parameters and presets (:mod:`.spec`), the stage driver
(:mod:`.driver`), the bulk measures of its curves (:mod:`.measures`), its results
(:mod:`.results`) and the checkpoints of a run in flight (:mod:`.checkpoint`)."""
