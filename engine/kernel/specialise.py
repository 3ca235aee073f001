"""Scene-specialised step kernels.

:func:`scene_features` says which features a scene uses; :func:`load_kernel` returns a module
compiled for exactly those, with :func:`pair_slots` and :func:`wall_slots` naming the
parameter slots it reads (generated from the same flags). The module is the step template with
its feature block rewritten, written once to ``<cache_dir>/kernels/step_<hash>.py`` and imported
from there, so numba caches its machine code on disk like any module's. The hash covers the
flags and the source of every file the kernels are compiled from (and the numba version):
editing a law can never reuse a stale binary, which numba's own cache (keyed on the caller's
file only) would do.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import re
import sys
import tempfile
import threading
from pathlib import Path
from types import ModuleType

import numba

from ..core.config import cache_dir

#: The compile-time switches, in template order, with what each one adds.
FEATURES: dict[str, str] = {
    "pair_hertz": "Hertz-Mindlin pair law instead of the bilinear law",
    "adhesion": "adhesive force f0 of the bilinear law",
    "adhesive_branch": "adhesive branch slope kadh of the bilinear law",
    "plastic": "plastic unloading branch (k2 > k1) of the bilinear law",
    "friction": "pair tangential spring, friction cap and tangential history",
    "rolling": "pair rolling resistance",
    "damping": "pair viscous damping",
    "eepa": "non-linear EEPA branches d^n, d^chi (engine.EEPA)",
    "normal_cap": "friction cap on the total normal force (EEPA friction_cap='normal')",
    "periodic_x": "minimum image along x",
    "periodic_y": "minimum image along y",
    "periodic_z": "minimum image along z",
    "walls": "planar walls",
    "wall_friction": "wall tangential spring and friction",
    "wall_rolling": "wall rolling resistance",
    "wall_damping": "wall damping",
    "gravity": "gravity",
}

#: Every named parameter slot of the pair laws, with the feature that needs it (None: always
#: read). Bilinear and EEPA: k1, k2, kadh, kt [N/m, EEPA N/m^n and N/m^chi], f0 [N], zeta,
#: mu_s, mu_r [-], EEPA exponents n, chi [-]; Hertz-Mindlin:
#: e_star, g_star [Pa], zeta, mu_s, mu_r [-] (see the records' ``kernel_params``).
PAIR_SLOTS: dict[str, tuple[tuple[str, str | None], ...]] = {
    "bilinear": (
        ("k1", None),
        ("k2", "plastic"),
        ("f0", "adhesion"),
        ("kadh", "adhesive_branch"),
        ("kt", "friction"),
        ("zeta", "damping"),
        ("mu_s", "friction"),
        ("mu_r", "rolling"),
        ("n", "eepa"),
        ("chi", "eepa"),
    ),
    "hertz": (
        ("e_star", None),
        ("g_star", "friction"),
        ("zeta", "damping"),
        ("mu_s", "friction"),
        ("mu_r", "rolling"),
    ),
}
#: The wall law's (Hertz-Mindlin) slots, with the feature that needs each.
WALL_SLOTS: tuple[tuple[str, str | None], ...] = (
    ("e_star", None),
    ("g_star", "wall_friction"),
    ("zeta", "wall_damping"),
    ("mu_s", "wall_friction"),
    ("mu_r", "wall_rolling"),
)
#: The slot constants the template reads: PAIR_<NAME> for both pair laws, WALL_<NAME>.
_PAIR_NAMES = (
    "k1",
    "k2",
    "f0",
    "kadh",
    "kt",
    "e_star",
    "g_star",
    "zeta",
    "mu_s",
    "mu_r",
    "n",
    "chi",
)

_ENGINE = Path(__file__).resolve().parents[1]
_TEMPLATE = _ENGINE / "kernel" / "step_template.py"
#: What a specialised module is compiled from: the template, the kernel's own modules, the
#: contact laws (their scalar kernels and composition) and the configuration.
_DEPENDENCIES = ("core", "contact", "kernel")
_BLOCK = re.compile(r"# >>> features.*?# <<< features", re.S)
_loaded: dict[tuple, ModuleType] = {}
_lock = threading.Lock()


def scene_features(scene, periodic: tuple[bool, bool, bool] | None = None) -> dict[str, bool]:
    """The features ``scene`` uses (``periodic`` overrides the scene's periodic flags)."""
    per = scene.periodic if periodic is None else tuple(bool(p) for p in periodic)
    f = dict.fromkeys(FEATURES, False)
    f.update(scene.pair_law.pair_features())  # each law says what it switches on
    f.update(periodic_x=per[0], periodic_y=per[1], periodic_z=per[2])
    if scene.walls:
        f["walls"] = True
        f.update(scene.wall_law.wall_features())
    f["gravity"] = any(g != 0 for g in scene.gravity)
    return f


def pair_slots(features: dict[str, bool]) -> tuple[str, ...]:
    """Names of the pair-law parameters the kernel for ``features`` reads, in slot order."""
    family = "hertz" if features["pair_hertz"] else "bilinear"  # a law's ``kernel``
    return tuple(name for name, need in PAIR_SLOTS[family] if need is None or features[need])


def wall_slots(features: dict[str, bool]) -> tuple[str, ...]:
    """Names of the wall-law parameters the kernel for ``features`` reads, in slot order
    (none without walls)."""
    if not features["walls"]:
        return ()
    return tuple(name for name, need in WALL_SLOTS if need is None or features[need])


def _slot_lines(prefix: str, names: tuple[str, ...], slots: tuple[str, ...]) -> str:
    # a parameter without a slot points past the used ones, at the trailing NaN
    return "".join(
        f"{prefix}_{name.upper()} = {slots.index(name) if name in slots else len(slots)}\n"
        for name in names
    )


_CALL = re.compile(r"\n( *)# >>> _particle_one.*?# <<< _particle_one\n", re.S)
_FUNC = re.compile(r"\ndef _particle_one\(.*?\):\n    \"\"\".*?\"\"\"\n(.*?)    return e2\n", re.S)


def _inline_particle_pass(src: str) -> str:
    """The CPU chunk loop of the particle pass with :func:`_particle_one`'s body written in
    place of the call (its parameters have the names of the chunk's variables, and its one
    ``return e2`` ends it): called as an inlined function, the pass ran 4x slower on the CPU
    (numba's reference counting around the call). The function itself stays, for CUDA."""
    body = _FUNC.search(src)
    call = _CALL.search(src)
    if body is None or call is None:
        raise RuntimeError("step template: _particle_one or its call marker not found")
    pad = call.group(1)[4:]  # the body is indented once; the call sits in the chunk's loop
    text = "".join(
        pad + line if line.strip() else line for line in body.group(1).splitlines(keepends=True)
    )
    return src[: call.start()] + "\n" + text + src[call.end() :]


def _source(features: dict[str, bool]) -> str:
    unknown = set(features) - set(FEATURES)
    if unknown or set(FEATURES) - set(features):
        raise ValueError(f"features must be exactly {sorted(FEATURES)}")
    block = "# >>> features (generated by engine.kernel.specialise)\n"
    block += "".join(f"{name.upper()} = {bool(features[name])}\n" for name in FEATURES)
    block += _slot_lines("PAIR", _PAIR_NAMES, pair_slots(features))
    block += _slot_lines("WALL", tuple(n for n, _ in WALL_SLOTS), wall_slots(features))
    block += "# <<< features"
    return _inline_particle_pass(_BLOCK.sub(lambda _m: block, _TEMPLATE.read_text(), count=1))


def kernel_digest(features: dict[str, bool]) -> str:
    """Hash naming the specialised module: flags, kernel sources, numba and Python versions."""
    h = hashlib.sha256(_source(features).encode())
    for package in _DEPENDENCIES:
        for f in sorted((_ENGINE / package).rglob("*.py")):
            h.update(f.relative_to(_ENGINE).as_posix().encode())
            h.update(f.read_bytes())
    h.update(f"{numba.__version__} {sys.version_info[:2]}".encode())
    return h.hexdigest()[:20]


def _kernel_dir() -> Path:
    d = cache_dir() / "kernels"
    try:
        d.mkdir(parents=True, exist_ok=True)
        probe = d / f".w{os.getpid()}"
        probe.touch()
        probe.unlink()
    except OSError:
        d = Path(tempfile.gettempdir()) / f"demscale-{os.getuid()}" / "kernels"
        d.mkdir(parents=True, exist_ok=True)
    return d


def load_kernel(features: dict[str, bool]) -> ModuleType:
    """The step module compiled for ``features`` (see :data:`FEATURES`)."""
    key = tuple(sorted(features.items()))
    with _lock:
        if key in _loaded:
            return _loaded[key]
        digest = kernel_digest(features)
        path = _kernel_dir() / f"step_{digest}.py"
        if not path.exists():
            # written once, never replaced: numba's cache is keyed on this file's mtime, and
            # several processes (test workers, service workers) may race to create it
            fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
            with os.fdopen(fd, "w") as fh:
                fh.write(_source(features))
            try:
                os.link(tmp, path)
            except FileExistsError:
                pass
            finally:
                os.unlink(tmp)
        name = f"_demscale_step_{digest}"
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
        _loaded[key] = module
        return module
