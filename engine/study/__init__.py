"""Scaling studies: the spec and rules (:mod:`.spec`), the runs they plan (:mod:`.plan`),
running them (:mod:`.run`, with :mod:`.channel` for runs elsewhere), and judging them: verdict
metrics (:mod:`.metrics`), intervals (:mod:`.intervals`), verdicts (:mod:`.judge`), seeds
until decided (:mod:`.loop`), the typed report (:mod:`.report`, built by :mod:`.advice`),
the assembled result (:mod:`.results`)."""
