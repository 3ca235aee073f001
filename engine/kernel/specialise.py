"""Scene-specialised step kernels.

:func:`scene_features` says what a scene uses: the kernel family of its pair law and of its
wall law (``pair_kernel``, ``wall_kernel``) and the compile-time switches, those of each side
(the composition's and the family's own; the wall side's prefixed ``wall_``) and the scene's
(periodic axes, walls, meshes, gravity). :func:`load_kernel` returns a module compiled for
exactly those, with :func:`pair_slots` and :func:`wall_slots` naming the parameter slots it
reads. A scene without meshes has ``meshes`` off and compiles the kernel it compiled before
meshes existed (their code is a branch on that constant).

The module is the step template with its feature block generated: the two families imported
from their law modules, every switch as a constant, and the readers of the two parameter
tuples (a switched-off parameter takes its neutral value, a constant the compiler folds). It
is written once to ``<cache_dir>/kernels/step_<hash>.py`` and imported from there, so numba
caches its machine code on disk like any module's. The hash covers the features and the
source of every file the kernels are compiled from, the law modules included (and the numba
version): editing a law can never reuse a stale binary, which numba's own cache (keyed on the
caller's file only) would do. Nothing here knows a particular law: each family
(:class:`engine.contact.kernel.LawKernel`) says what it needs.
"""

from __future__ import annotations

import ast
import hashlib
import importlib.util
import io
import os
import re
import sys
import tempfile
import textwrap
import threading
import tokenize
from pathlib import Path
from types import ModuleType

import numba

from ..contact.kernel import COMPOSITION_SWITCHES, LawKernel
from ..contact.registry import LAWS, kernel_named, wall_laws
from ..core.config import cache_dir

#: The scene's own switches.
SCENE_SWITCHES: dict[str, str] = {
    "periodic_x": "minimum image along x",
    "periodic_y": "minimum image along y",
    "periodic_z": "minimum image along z",
    "walls": "planar walls",
    "meshes": "triangle-mesh walls (engine.Mesh: candidate triangles, face/edge/vertex contacts)",
    "gravity": "gravity",
}

#: The two kernel-family features: which family a side's law belongs to.
FAMILY_FEATURES: dict[str, str] = {
    "pair_kernel": "kernel family of the pair law (its LawKernel's name)",
    "wall_kernel": "kernel family of the wall law",
}


def side_switches(kernel: LawKernel, side: str) -> dict[str, str]:
    """The switches of one side of a scene with a law of family ``kernel``, name -> what it
    adds: the composition's, then the family's own; the wall side's prefixed ``wall_``."""
    prefix = "" if side == "pair" else "wall_"
    out = {f"{prefix}{k}": f"{side} {v}" for k, v in COMPOSITION_SWITCHES.items()}
    out.update({f"{prefix}{k}": f"{side} {v}" for k, v in kernel.switches.items()})
    clash = set(out) & set(SCENE_SWITCHES)
    if clash:
        raise ValueError(f"kernel {kernel.name}: switches {sorted(clash)} clash with the scene's")
    return out


def feature_names(pair_kernel: LawKernel, wall_kernel: LawKernel) -> tuple[str, ...]:
    """Every feature of a scene whose laws have these families, in the template's order."""
    return (
        *FAMILY_FEATURES,
        *side_switches(pair_kernel, "pair"),
        *side_switches(wall_kernel, "wall"),
        *SCENE_SWITCHES,
    )


def _catalogue() -> dict[str, str]:
    out = dict(FAMILY_FEATURES)
    for law in LAWS.values():
        if law.pair:
            out.update(side_switches(law.kernel, "pair"))
    for law in LAWS.values():
        if law.wall:
            out.update(side_switches(law.kernel, "wall"))
    out.update(SCENE_SWITCHES)
    return out


#: Every feature of the registered laws' kernels, with what it adds (a scene's features are
#: those of its two families: :func:`feature_names`).
FEATURES: dict[str, str] = _catalogue()

_ENGINE = Path(__file__).resolve().parents[1]
_TEMPLATE = _ENGINE / "kernel" / "step_template.py"
#: What a specialised module is compiled from: the template, the kernel's own modules, the
#: contact composition and laws, and the configuration (plus the modules of the two families,
#: wherever they are defined).
_DEPENDENCIES = ("core", "contact", "kernel")
_BLOCK = re.compile(r"# >>> features.*?# <<< features", re.S)
_loaded: dict[tuple, ModuleType] = {}
_lock = threading.Lock()


def _side(prefix: str, kernel: LawKernel, law=None) -> dict[str, bool]:
    """One side's switches: every switch of its family present, False unless ``law`` turns
    it on (all False without a law: the side is never called)."""
    names = kernel.switch_names
    states = law.switches() if law is not None else {}
    unknown = set(states) - set(names)
    if unknown:
        raise ValueError(
            f"{type(law).__name__}.switches() names {sorted(unknown)}, not switches of its "
            f"kernel {kernel.name} ({list(names)})"
        )
    return {f"{prefix}{k}": bool(states.get(k, False)) for k in names}


#: ``DEMSCALE_KERNELS``: ``scene`` (the default) compiles each scene's kernel with exactly the
#: switches it uses; ``general`` switches on every switch that has a neutral value, so that
#: scenes differing only in those share one kernel (per pair of families, friction caps,
#: periodic axes, and meshes or none). Held to the scene's kernel bit for bit (a zero's sign
#: aside) for the default study's laws and four more cases (tests/engine/test_kernels.py;
#: EEPA and toy families not compared); each step costs more, and far fewer kernels are
#: compiled: for a test suite or a session of many small scenes, where compiling (tens of
#: seconds a kernel) outweighs stepping. Production runs keep ``scene``.
KERNELS_ENV = "DEMSCALE_KERNELS"
KERNEL_MODES = ("scene", "general")
#: Features that are not switches with a neutral value: the two families and the friction
#: caps on the total normal force (another convention).
NOT_NEUTRAL = (*FAMILY_FEATURES, "normal_cap", "wall_normal_cap")
#: Features a general kernel keeps as the scene has them: those, the periodic axes (a
#: minimum image along an axis without a period would be meaningless) and the meshes (a
#: neutral switch, but the triangle contacts are two fifths of a kernel's compile time,
#: 25 s of CPU against 15 s without them, measured 2026-12-07: the many scenes of planes
#: only pay them for the few of meshes).
KEPT_IN_GENERAL = (*NOT_NEUTRAL, "periodic_x", "periodic_y", "periodic_z", "meshes")


def kernel_mode() -> str:
    """The kernel mode from ``DEMSCALE_KERNELS`` (read at each call), ``scene`` unless set."""
    mode = os.environ.get(KERNELS_ENV, "scene").strip().lower() or "scene"
    if mode not in KERNEL_MODES:
        raise ValueError(f"{KERNELS_ENV} = {mode!r}: must be one of {', '.join(KERNEL_MODES)}")
    return mode


def kernel_features(features: dict, mode: str | None = None) -> dict:
    """The features of the kernel that runs a scene of ``features`` (:func:`scene_features`)
    in ``mode`` (default: the current :func:`kernel_mode`): the same in ``scene`` mode; in
    ``general`` mode every switch on but those of :data:`KEPT_IN_GENERAL`."""
    if (mode or kernel_mode()) == "scene":
        return dict(features)
    return {k: (v if k in KEPT_IN_GENERAL else True) for k, v in features.items()}


def scene_features(scene, periodic: tuple[bool, bool, bool] | None = None) -> dict:
    """The features ``scene`` uses (``periodic`` overrides the scene's periodic flags)."""
    per = scene.periodic if periodic is None else tuple(bool(p) for p in periodic)
    pair = scene.pair_law.kernel
    # without walls or meshes the wall side is never called: the scene's wall law, or any
    # wall law's family, fills it
    meshes = bool(getattr(scene, "meshes", ()))
    wall = (scene.wall_law or wall_laws()[0]).kernel
    f: dict = {"pair_kernel": pair.name, "wall_kernel": wall.name}
    f.update(_side("", pair, scene.pair_law))  # each law says what it switches on
    f.update(_side("wall_", wall, scene.wall_law if scene.walls or meshes else None))
    f.update(periodic_x=per[0], periodic_y=per[1], periodic_z=per[2])
    f["walls"] = bool(scene.walls)
    f["meshes"] = meshes  # off: the kernel of a scene of planes only, as before meshes
    f["gravity"] = any(g != 0 for g in scene.gravity)
    return f


def _kernels(features: dict) -> tuple[LawKernel, LawKernel]:
    return kernel_named(features["pair_kernel"]), kernel_named(features["wall_kernel"])


def _unprefixed(features: dict, kernel: LawKernel, prefix: str) -> dict[str, bool]:
    return {k: features[f"{prefix}{k}"] for k in kernel.switch_names}


def pair_slots(features: dict) -> tuple[str, ...]:
    """Names of the pair-law parameters the kernel for ``features`` reads, in slot order."""
    kernel = kernel_named(features["pair_kernel"])
    return kernel.used_slots(_unprefixed(features, kernel, ""))


def wall_slots(features: dict) -> tuple[str, ...]:
    """Names of the wall-law parameters the kernel for ``features`` reads, in slot order
    (none without walls or meshes)."""
    if not (features["walls"] or features["meshes"]):
        return ()
    kernel = kernel_named(features["wall_kernel"])
    return kernel.used_slots(_unprefixed(features, kernel, "wall_"))


def _reader(name: str, kernel: LawKernel, used: tuple[str, ...], side: str) -> str:
    """Source of the reader of one side's parameter tuple: a used slot is read from its
    place in the array, a switched-off one is its neutral value (a number, or the value of
    the slot it stands for)."""
    by_name = {s.name: s for s in kernel.slots}

    def value(slot_name: str, depth: int = 0) -> str:
        if slot_name in used:
            return f"p[{used.index(slot_name)}]"
        neutral = by_name[slot_name].neutral
        if isinstance(neutral, str):
            if depth > len(by_name):
                raise ValueError(f"kernel {kernel.name}: neutral values of {slot_name} loop")
            return value(neutral, depth + 1)
        return repr(float(neutral))

    args = ", ".join(value(s.name) for s in kernel.slots)
    return (
        f"\n\n@njit(**NJIT_INLINE)\ndef {name}(p):\n"
        f'    """The {side} law\'s parameters from their slots (generated: a parameter this '
        f'scene does\n    not use has no slot and takes its neutral value)."""\n'
        f"    return {side.title()}Params({args})\n"
    )


def _flags(name: str, kernel: LawKernel, prefix: str, side: str) -> str:
    args = ", ".join(f"{prefix.upper()}{k.upper()}" for k in kernel.switch_names)
    return (
        f"\n\n@njit(**NJIT_INLINE)\ndef {name}():\n"
        f'    """The {side} law\'s switches (compile-time constants)."""\n'
        f"    return {side.title()}Switches({args})\n"
    )


def features_block(features: dict) -> str:
    """The generated feature block of the step template for ``features``."""
    pair, wall = _kernels(features)
    names = feature_names(pair, wall)
    if set(features) != set(names):
        raise ValueError(f"features must be exactly {sorted(names)}, not {sorted(features)}")
    block = "# >>> features (generated by engine.kernel.specialise)\n"
    block += f"PAIR_KERNEL = importlib.import_module({pair.module!r}).{pair.attribute}\n"
    block += f"WALL_KERNEL = importlib.import_module({wall.module!r}).{wall.attribute}\n\n"
    block += "".join(f"{n.upper()} = {bool(features[n])}\n" for n in names[len(FAMILY_FEATURES) :])
    block += f"PAIR_EFFECTIVE_RADIUS = {bool(pair.effective_radius)}\n"
    block += "PairParams = PAIR_KERNEL.params\nPairSwitches = PAIR_KERNEL.switch_tuple\n"
    block += "WallParams = WALL_KERNEL.params\nWallSwitches = WALL_KERNEL.switch_tuple\n"
    block += _reader("_pair_law", pair, pair_slots(features), "pair")
    block += _flags("_pair_flags", pair, "", "pair")
    block += _reader("_wall_law", wall, wall_slots(features), "wall")
    block += _flags("_wall_flags", wall, "wall_", "wall")
    block += "# <<< features"
    return block


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


_MESH_CALL = re.compile(r"\n( *)# >>> _mesh_one.*?\n(.*?)\n *# <<< _mesh_one\n", re.S)


def _inline_mesh_contacts(src: str) -> str:
    """:func:`_particle_one` with :func:`_mesh_one`'s body written in place of its call (for
    both targets): its local names prefixed ``_m_``, each parameter the argument's own name
    where the argument is a name (an array bound to a local of its own would cost a
    reference count per particle, as the call did), else a local set to the argument's
    expression; its one ``return`` (its last line) assigns the call's targets. The
    function itself stays (unused)."""
    tree = ast.parse(src)
    fn = next(n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == "_mesh_one")
    params = [a.arg for a in fn.args.args]
    local = set(params) | {
        n.id for n in ast.walk(fn) if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Store)
    }
    ret = fn.body[-1]
    if not isinstance(ret, ast.Return) or any(
        isinstance(n, ast.Return) for stmt in fn.body[:-1] for n in ast.walk(stmt)
    ):
        raise RuntimeError("step template: _mesh_one must end in its one return")
    lines = src.splitlines(keepends=True)
    first = fn.body[1] if isinstance(fn.body[0], ast.Expr) else fn.body[0]  # after the doc
    body = "".join(lines[first.lineno - 1 : ret.lineno - 1])
    call = _MESH_CALL.search(src)
    if call is None:
        raise RuntimeError("step template: the call of _mesh_one or its markers not found")
    stmt = ast.parse(textwrap.dedent(call.group(2))).body[0]
    targets = [t.id for t in stmt.targets[0].elts]
    args = [ast.unparse(a) for a in stmt.value.args]
    names = {p: f"_m_{p}" for p in local}
    binds = []
    for p, a in zip(params, args, strict=True):
        if a.isidentifier():
            names[p] = a
        else:
            binds.append(f"_m_{p} = {a}\n")

    def rename(text: str) -> str:
        out = []
        prev = None
        for tok in tokenize.generate_tokens(io.StringIO(text).readline):
            if tok.type == tokenize.NAME and tok.string in names and prev != ".":
                tok = tok._replace(string=names[tok.string])
            out.append(tok)
            prev = tok.string
        return tokenize.untokenize(out)

    values = ", ".join(names[e.id] for e in ret.value.elts)
    text = "".join(binds) + textwrap.dedent(rename(body)) + f"{', '.join(targets)} = {values}\n"
    pad = call.group(1)
    text = "".join(pad + line if line.strip() else line for line in text.splitlines(True))
    return src[: call.start()] + "\n" + text + src[call.end() :]


def _source(features: dict) -> str:
    block = features_block(features)
    src = _BLOCK.sub(lambda _m: block, _TEMPLATE.read_text(), count=1)
    return _inline_particle_pass(_inline_mesh_contacts(src))


def _module_file(kernel: LawKernel) -> Path | None:
    spec = importlib.util.find_spec(kernel.module)
    return Path(spec.origin) if spec is not None and spec.origin else None


def kernel_digest(features: dict) -> str:
    """Hash naming the specialised module: features, kernel sources (the engine's and the two
    families' modules), numba and Python versions."""
    h = hashlib.sha256(_source(features).encode())
    for package in _DEPENDENCIES:
        for f in sorted((_ENGINE / package).rglob("*.py")):
            h.update(f.relative_to(_ENGINE).as_posix().encode())
            h.update(f.read_bytes())
    for kernel in _kernels(features):
        f = _module_file(kernel)
        if f is not None and f.exists():
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


def compiled_member(module: ModuleType, args: tuple):
    """``module.run_member`` compiled for ``args`` (the member's arguments after its rank),
    once across processes: the first process to need a kernel compiles it (tens of seconds)
    while holding a lock file beside its source (``step_<digest>.lock``, ``flock``); the
    others wait, then load what it wrote to numba's cache instead of compiling it again
    (test workers, service workers and pool processes starting together on a cold cache).
    A process killed while compiling drops its lock. Without ``fcntl`` (not POSIX) each
    process compiles as before."""
    member = module.run_member
    if member.signatures:
        return member
    signature = tuple(numba.typeof(a) for a in (0, *args))
    try:
        import fcntl
    except ImportError:  # pragma: no cover - POSIX only
        member.compile(signature)
        return member
    with open(Path(module.__file__).with_suffix(".lock"), "a") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            if not member.signatures:
                member.compile(signature)  # numba's cache first: a loaded kernel if written
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)
    return member
