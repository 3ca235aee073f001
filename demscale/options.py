"""What the ``demscale`` commands share: their argparse options, declared once (each command
passes its own help text where it words one differently), the check of an installed
extra, and how an error is printed. Nothing here imports more than the standard library:
``demscale --help`` needs only the engine."""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
from pathlib import Path

#: The help formatter of every command (the help texts are laid out by hand).
FORMAT = argparse.RawDescriptionHelpFormatter

#: What ``--out`` means where the command writes its results (``study``, ``run``).
OUT_HELP = "folder for the results (created if missing; files are overwritten)"

#: How an error is printed on the console: one line however long (a log or a test reads
#: it whole), red, and its text as it is (an engine field such as ``coarse_radii[0]`` is no
#: rich markup).
ERROR = {"style": "red", "markup": False, "highlight": False, "soft_wrap": True}


def command(sub, name: str, help: str, description: str, func) -> argparse.ArgumentParser:
    """A subcommand ``name`` on the subparsers ``sub``, with its one-line ``help``, its
    help text ``description`` and the function ``func(args) -> exit status`` that runs it."""
    p = sub.add_parser(name, help=help, description=description, formatter_class=FORMAT)
    p.set_defaults(func=func)
    return p


def add_out(p: argparse.ArgumentParser, help: str = OUT_HELP) -> None:
    """``--out`` / ``-o DIR``, required: where the command writes."""
    p.add_argument("--out", "-o", metavar="DIR", required=True, help=help)


def add_workers(p: argparse.ArgumentParser, help: str) -> None:
    """``--workers`` / ``-j N`` (default 1): runs side by side in N processes."""
    p.add_argument("--workers", "-j", type=int, default=1, metavar="N", help=help)


def add_quiet(p: argparse.ArgumentParser, help: str) -> None:
    """``--quiet`` / ``-q``: no progress bars."""
    p.add_argument("--quiet", "-q", action="store_true", help=help)


def add_backend(p: argparse.ArgumentParser) -> None:
    """``--backend {cpu,cuda,auto}`` (default: DEMSCALE_BACKEND, else cpu)."""
    p.add_argument(
        "--backend",
        choices=("cpu", "cuda", "auto"),
        default=None,
        help="where the engine runs: cpu, cuda (an NVIDIA GPU, the gpu extra) or "
        "auto (the GPU when usable); default: DEMSCALE_BACKEND, else cpu",
    )


def add_data_dir(p: argparse.ArgumentParser, help: str) -> None:
    """``--data-dir DIR`` (default None: DEMSCALE_DATA_DIR, else ./var)."""
    p.add_argument("--data-dir", type=Path, default=None, metavar="DIR", help=help)


def workers_error(workers: int) -> str | None:
    """Why ``--workers`` is not a number of processes, or None."""
    return None if workers >= 1 else f"--workers {workers}: must be at least 1"


def attempt(
    read, cannot: str, invalid: str, unreadable=(OSError, json.JSONDecodeError), refused=()
):
    """``read()``'s value and None, or None and why it failed: ``"{cannot}: {error}"`` where
    a file cannot be read (``unreadable``), ``"{invalid}: {error}"`` where its content is
    refused (the engine's :class:`engine.ParameterError`, TypeError, ValueError and the
    errors in ``refused``). The command prints the message and exits with 2."""
    from engine.core.errors import ParameterError

    try:
        return read(), None
    except unreadable as e:
        return None, f"{cannot}: {e}"
    except (ParameterError, TypeError, ValueError, *refused) as e:
        return None, f"{invalid}: {e}"


def lacks_extra(command: str, modules, extra: str) -> bool:
    """Tell the user which extra ``command`` needs when one of ``modules`` is not
    installed; True then (the command exits with 2)."""
    missing = [m for m in modules if importlib.util.find_spec(m) is None]
    if missing:
        print(
            f'demscale {command} needs {", ".join(missing)}: pip install "demscale[{extra}]"',
            file=sys.stderr,
        )
    return bool(missing)


#: What ``study`` and ``run`` need: the ``cli`` extra.
CLI_EXTRA = ("rich", "h5py", "matplotlib")


def single_test(test, command: str, hint: str = ""):
    """``test`` if it is of a kind ``command`` takes alone (a uniaxial test or a hopper: the
    kinds ``demscale run`` runs and ``export-test`` writes a deck of), else a ValueError
    naming the command and the kind (and ``hint``)."""
    from engine.hopper.spec import HopperTest
    from engine.uniaxial.spec import UniaxialTest

    if not isinstance(test, (UniaxialTest, HopperTest)):
        raise ValueError(
            f"demscale {command} takes a UniaxialTest or a HopperTest, not a "
            f"{type(test).__name__}{hint}"
        )
    return test
