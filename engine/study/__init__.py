"""Scaling studies: the spec and rules (:mod:`.spec`), the runs they plan (:mod:`.plan`),
running them (:mod:`.run`, with :mod:`.channel` for runs elsewhere), and judging them: verdict
metrics (:mod:`.metrics`), intervals (:mod:`.intervals`), verdicts and advice
(:mod:`.advisor`), seeds until decided (:mod:`.adaptive`), the assembled result
(:mod:`.results`)."""
