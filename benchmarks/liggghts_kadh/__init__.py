"""demscale's adhesive branch (kadh) against LIGGGHTS' ``fixKc on``: compare.py."""
