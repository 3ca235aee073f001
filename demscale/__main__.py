"""``python -m demscale ...``: the same as the ``demscale`` command."""

from demscale.cli import main

raise SystemExit(main())
