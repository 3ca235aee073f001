"""The ``demscale`` command line: the parser of its commands and the entry point.

    demscale study SPEC.json --out DIR [--workers N]   run a scaling study here
    demscale run TEST.json --out DIR                    one uniaxial test, with snapshots
    demscale calibrate TARGETS.json --test T.json ...   a law fitted to laboratory data
    demscale export LAW.json [--radius R]               a law for LIGGGHTS, or as a table
    demscale serve [--host H] [--port P]                the job service's HTTP API
    demscale worker [--once]                            a worker of the job service

Each command is a module of :mod:`demscale.commands` (its help text, its options, the
function that runs it); the options they share are declared once in
:mod:`demscale.options`, the progress display is :mod:`demscale.progress`, what they write
and print :mod:`demscale.report`. ``demscale --help`` and the commands' own ``--help``
need only the engine; ``study`` needs the ``cli`` extra (rich, h5py, matplotlib), ``serve``
and ``worker`` the ``service`` extra.
"""

from __future__ import annotations

import argparse
import os
import sys

from .commands import MODULES
from .commands.serve import job
from .options import FORMAT

DESCRIPTION = """\
demscale: coarse-graining studies for cohesive DEM. How large can the particles be, and how
must the contact parameters scale with their size, before the bulk behaviour changes?

A study runs a fine reference (uniaxial test: fill, consolidation, unloading, unconfined
compression to failure) and coarser variants under scaling rules, then judges each variant
against the reference's seed-to-seed noise."""


def parser() -> argparse.ArgumentParser:
    """The argument parser of the ``demscale`` command."""
    ap = argparse.ArgumentParser(
        prog="demscale",
        description=DESCRIPTION,
        formatter_class=FORMAT,
        epilog="examples:\n"
        "  demscale study examples/quick_study.json --out results/quick\n"
        "  demscale study my_study.json --out results/mine --workers 4\n"
        "  demscale run examples/quick_test.json --out results/one "
        "--snapshot-interval 0.02\n"
        "  demscale serve --port 8000          then open http://127.0.0.1:8000/\n"
        "  demscale job --exit                 the main job: the default study "
        "through the service\n"
        "run `demscale COMMAND --help` for the options of each command.",
    )
    ap.add_argument("--version", action="version", version=f"demscale {_version()}")
    sub = ap.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for module in MODULES:
        module.add_commands(sub)
    return ap


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("demscale")
    except PackageNotFoundError:
        return "(not installed)"


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``demscale`` console script."""
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        if argv[:1] == ["job"]:
            return job(argv[1:])
        args = parser().parse_args(argv)
        return args.func(args)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # the reader went away (`demscale export law.json | head -1`): nothing to say to
        # it; stdout goes to /dev/null so that the interpreter's own flush at exit is quiet
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 141  # 128 + SIGPIPE, as a program the signal stopped
