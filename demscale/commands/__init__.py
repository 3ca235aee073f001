"""The ``demscale`` commands, a module each: ``add_commands(sub)`` puts its subcommands on
the parser's subparsers (each with ``func(args) -> exit status``); the functions import
what they run (the engine's heavy parts, rich, the service) only when called, so that
``demscale --help`` needs only the engine.

``job`` (the main job, ``job.py``) parses its own arguments; ``serve.py`` registers it."""

from __future__ import annotations

from . import calibrate, deck, export, plan, run, serve, study

#: The modules in the order their commands are listed by ``demscale --help``.
MODULES = (study, run, calibrate, export, serve, deck, plan)
