"""The ``demscale`` command: run a study from a JSON file with the engine alone
(``demscale study``), or start the job service's API (``demscale serve``) and worker
(``demscale worker``). See :mod:`demscale.cli` and ``demscale --help``."""
