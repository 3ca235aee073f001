"""A hopper discharge, whole, as a LIGGGHTS 3.8 input deck (docs/HOPPER.md).

:func:`write_hopper_deck` writes a folder that LIGGGHTS runs unmodified (``liggghts -in
in.hopper`` there), the same hopper :func:`engine.run_hopper` runs, so that a user can judge
the discharge in their own code:

=================  ==================================================================
demscale           LIGGGHTS 3.8
=================  ==================================================================
scene              the box of :func:`engine.hopper.scene.build_hopper`; a slot is
                   periodic in its depth (``boundary f p f``), a cone walled
                   (``boundary f f f``)
the poured fill    ``read_data fill.data``: demscale's own lattice fill (the particles
                   :func:`engine.hopper.scene.lattice_fill` places, with their radii),
                   so that both codes start from the same spheres
hopper walls       the walls' triangle meshes as STL (``wall_*.stl``: a slot's two flat
                   walls, a cone's polygonal frustum of 32 sides), ``fix
                   mesh/surface/stress`` with Hertz-Mindlin ``wall/gran`` of atom type
                   2 (E, nu of ``wall_material``), the wall friction ``wall_law.mu``
gate               ``gate.stl``, the same; closed during the settling, then moved down
                   at ``gate_speed`` (``move/mesh linear``) for as many steps as
                   demscale moves it, and stopped below the catch floor
catch floor        a ``primitive zplane`` at demscale's catch depth (exact: demscale's
                   floor is an infinite plane)
pair law           what the law's LIGGGHTS mapping declares (engine.contact.export):
                   ``edinburgh/stiffness`` for the bilinear and EEPA laws, ``hertz``
settling           samples every ``output_interval`` until two free-fall times from
                   the walls' top have passed and the kinetic energy is below
                   ``settle_ke`` N m g R (``max_settle_time``: an error line, stop)
discharge          the gate opened; one sample every ``output_interval`` until no
                   particle is left above the discharge level (one largest diameter
                   below the outlet), the flow has stopped (below), or
                   ``max_discharge_time``
=================  ==================================================================

Output: ``discharge.txt`` (:data:`DISCHARGE_COLUMNS`: one line per sample of the settling
and of the discharge, the discharged mass [kg] among them, and ``#`` lines marking the
stages), ``dump/hopper_<step>.dump`` (id, type, x, y, z, vx, vy, vz, radius every
``dump_every`` samples, and the settled fill and the end) and ``log.liggghts``.

What the deck does differently from demscale is written in its comments
(:func:`hopper_differences`): the pair law's mapping's differences, and the deck's own (the
stop criterion on consecutive windows instead of a sliding one, mesh contacts resolved by
LIGGGHTS' own rule). What a deck cannot express raises :class:`engine.ParameterError`
naming the ``HopperTest`` field (:func:`engine.io.liggghts_deck.check_laws`).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..core.errors import ParameterError
from .liggghts_deck import (
    _materials,
    _num,
    _pair,
    _wall_model,
    check_laws,
    deck_head,
    granular_data,
)

#: Files of a hopper deck folder.
HOPPER_DECK = "in.hopper"
FILL = "fill.data"
GATE = "gate.stl"
HOPPER_TEST = "test.json"
#: What the deck writes there.
DISCHARGE = "discharge.txt"
HOPPER_LOG = "log.liggghts"
DUMP_DIR = "dump"

#: The columns of a sample line of :data:`DISCHARGE`, with units: the stage (0 settling,
#: 1 discharge), the step, the time [s] since the start (settling) or since the gate began
#: to open (discharge), the mass discharged (centres more than one largest diameter below
#: the outlet) and the rest [kg], translational and rotational kinetic energy [J], the
#: particles in the box.
DISCHARGE_COLUMNS = {
    "stage": "1",
    "step": "1",
    "time": "s",
    "discharged_mass": "kg",
    "remaining_mass": "kg",
    "ke_trans": "J",
    "ke_rot": "J",
    "particles": "1",
}

#: Verlet skin in radii of the largest particle (as the uniaxial deck's).
SKIN_RADII = 0.5
#: A particle dump every this many samples of the discharge, by default.
DUMP_EVERY = 10


def hopper_differences(test) -> list[str]:
    """What LIGGGHTS does differently from demscale in the deck of ``test`` (an
    :class:`engine.HopperTest`): the pair law's in a deck (its mapping's), then the deck's
    own."""
    pair = _pair(test, "HopperTest")
    out = list(pair.deck_differences)
    out += [
        "walls and gate: LIGGGHTS resolves a sphere's contact with a triangle mesh by its own "
        "rule (one contact per face, edge or corner it touches, merged where coplanar); "
        "LIGGGHTS caps wall friction at mu |F_n| with damping, demscale at mu times the "
        "elastic Hertz force",
        "the stop criterion reads consecutive windows of arch_wait free-fall times (LIGGGHTS' "
        "input language keeps no arrays), demscale's a sliding one sampled every "
        "output_interval: the deck may wait up to twice as long before it stops",
        "below the outlet: demscale parks every discharged grain whose centre falls 2 B + 10 "
        "largest diameters below the outlet (its sink: out of every contact, on a lattice "
        "below); the deck lets them fall freely onto the catch floor (the flow through the "
        "outlet feels neither)",
    ]
    if test.shape == "slot":
        out += list(pair.periodic_differences)
    return out


def _geometry(test):
    from ..hopper.scene import build_hopper

    return build_hopper(test)


def fill_data(test, positions: np.ndarray, radii: np.ndarray, box) -> str:
    """The poured fill as a LAMMPS data file (:func:`engine.io.liggghts_deck.granular_data`)
    in the box ``((xlo, xhi), (ylo, yhi), (zlo, zhi))`` [m], atom type 2 the walls'
    material."""
    title = "LAMMPS data file of a demscale hopper (engine.io.liggghts_hopper)"
    return granular_data(title, positions, radii, test.density, box)


def deck_meshes(test, geo) -> list:
    """The scene's meshes as the deck writes them: a slot's walls and gate cut to the
    periodic depth, y in [0, depth] (LIGGGHTS wraps a mesh around a periodic boundary
    itself, and would wrap demscale's overhang onto the walls a second time); a cone's as
    they are."""
    from ..simulation.mesh import Mesh

    meshes = list(geo.scene.meshes)
    if test.shape != "slot":
        return meshes
    out = []
    for m in meshes:
        v = np.array(m.vertices, dtype=float)
        v[:, 1] = np.clip(v[:, 1], 0.0, test.depth)
        out.append(Mesh(v, m.triangles, name=m.name))
    return out


def deck_box(geo) -> tuple[tuple[float, float], ...]:
    """The deck's box [m]: the scene's, reaching down below where the opened gate stops
    (LIGGGHTS refuses a mesh that leaves its box; no particle goes below the catch
    floor)."""
    (x, y, (zlo, zhi)) = geo.scene.box
    d = float(np.max(geo.scene.radii)) * 2.0
    return (tuple(x), tuple(y), (min(zlo, geo.gate_stop - d), zhi))


def _wall_files(geo) -> list[str]:
    """The STL file names of the hopper's walls (``geo.wall_meshes`` order)."""
    if len(geo.wall_meshes) == 1:
        return ["wall_cone.stl"]
    return [f"wall_{i}.stl" for i in range(len(geo.wall_meshes))]


class _HopperDeck:
    """Builds a hopper deck's lines."""

    def __init__(self, test, geo, skin: float, dump_every: int, max_steps: int | None):
        from ..hopper.driver import impact_speed, resolved_dt

        self.t = test
        self.geo = geo
        self.skin = skin
        self.dump_every = dump_every
        self.dt = resolved_dt(test, geo)
        self.impact = impact_speed(test, geo)
        self.S = max(1, round(test.output_interval / self.dt))
        # the opened gate moves this many steps, to below the catch floor (as demscale's)
        self.gate_steps = math.ceil(abs(geo.gate_stop) / (test.resolved_gate_speed * self.dt))
        self.max_steps = max_steps
        r = np.asarray(geo.scene.radii, dtype=float)
        self.masses = test.density * 4.0 / 3.0 * math.pi * r**3  # [kg]
        self.lines: list[str] = []

    def add(self, *lines: str) -> None:
        self.lines.extend(lines)

    def row(self, stage: int) -> None:
        values = "${n} ${tgate} ${mout} ${mrest} ${ket} ${ker} ${np}"
        self.add(f'print "{stage} {values}" append {DISCHARGE} screen no')

    def dump(self, label: str = "${n}") -> None:
        self.add(
            f"write_dump all custom {DUMP_DIR}/hopper_{label}.dump id type x y z vx vy vz "
            'radius modify sort id format "%d %d %.17g %.17g %.17g %.17g %.17g %.17g %.17g"'
        )

    def build(self) -> str:
        t, geo = self.t, self.geo
        d = t.max_diameter
        periodic = t.shape == "slot"
        walls = _wall_files(geo)
        names = [f"wall{i}" for i in range(len(walls))]
        self.add(
            f"# demscale hopper ({t.shape}) as a LIGGGHTS 3.8 deck (engine.io.liggghts_hopper),",
            f"# docs/HOPPER.md. Run it in this folder: liggghts -in {HOPPER_DECK}",
            f"# {t.n_particles} particles, R = {t.radius!r} m, outlet B = {t.outlet_width!r} m,",
            f"# half-angle {t.half_angle!r} deg, seed {t.seed}, pair law "
            f"{_pair(t, 'HopperTest').law},",
            f"# dt = {self.dt!r} s, a sample every {self.S} steps; every parameter of the",
            "# test is in test.json. LIGGGHTS does differently:",
        )
        for line in hopper_differences(t):
            self.add(f"#   - {line}")
        wall_model = _wall_model(t, "HopperTest")
        # sideways the box grows with the grains (the heap spreads on the catch floor;
        # demscale keeps a grain that leaves its box in its grid's edge cells)
        boundary = "boundary m p f" if periodic else "boundary m m f"
        self.add(
            "",
            *deck_head(
                HOPPER_LOG,
                boundary,
                FILL,
                self.skin,
                _materials(t, "HopperTest"),
                self.dt,
                t.gravity,
            ),
            "# the hopper's walls and the gate: demscale's triangle meshes",
            *(
                f"fix {n} all mesh/surface/stress file {f} type 2"
                for n, f in zip(names, walls, strict=True)
            ),
            f"fix gate all mesh/surface/stress file {GATE} type 2",
            f"fix walls all {wall_model} mesh n_meshes {len(names) + 1} meshes "
            + " ".join(names)
            + " gate",
            "# the catch floor: an infinite plane, as demscale's",
            f"fix floor all {wall_model} primitive type 2 zplane {_num(-geo.catch_depth)}",
            "",
            "# Variables. LIGGGHTS 3.8 redefines an equal-style variable by deleting it and",
            "# appending it anew, which shifts every later variable's index, and fixes and",
            "# computes keep the index they found at a run's set-up (runs here skip it): so the",
            "# variables a fix or compute reads come first and are never redefined.",
            "variable zero equal 0.0",
            "# the gate's speed: down at gate_speed for gate_steps steps after the opening",
            f"variable vgate equal {_num(-t.resolved_gate_speed)}"
            f"*((step-v_topen)<{self.gate_steps})",
            "# what a sample reads",
            f"variable lowz equal {_num(-d)}",
            "variable isout atom z<v_lowz",
            "variable mo atom mass*v_isout",
            "variable mr atom mass*(1-v_isout)",
            "compute msum all reduce sum v_mo v_mr",
            "compute ker all erotate/sphere",
            "variable n equal step",
            "variable topen equal 0",
            f"variable tgate equal (step-v_topen)*{_num(self.dt)}",
            "variable mout equal c_msum[1]",
            "variable mrest equal c_msum[2]",
            "variable ket equal ke(all)",
            "variable ker equal c_ker",
            "variable kin equal v_ket+v_ker",
            "variable np equal atoms",
            f"fix sample all ave/time {self.S} 1 {self.S} c_msum[1] c_msum[2] c_ker",
            "thermo_style custom step atoms ke c_msum[1] c_msum[2] c_ker",
            "thermo_modify norm no lost error",
            f"thermo {self.S}",
            f"shell mkdir {DUMP_DIR}",
            f'print "# demscale LIGGGHTS hopper output: {" ".join(DISCHARGE_COLUMNS)}" '
            f"file {DISCHARGE} screen no",
            "run 0",
        )
        self.settle()
        self.discharge()
        self.add(
            "",
            "label finish",
            f'print "# done ${{n}}" append {DISCHARGE} screen no',
        )
        self.dump("end")
        return "\n".join(self.lines) + "\n"

    def cut(self, stage: str, start: str) -> tuple[tuple[str, ...], tuple[str, ...]]:
        """With ``max_steps``: the stage ends after that many steps from ``start`` (a short
        check of the deck), marked ``# cut <stage> <step>``: the variable's definition (before
        the loop) and its check (in the loop)."""
        if self.max_steps is None:
            return (), ()
        return (f"variable {stage}cut equal (v_n-{start})>={self.max_steps}",), (
            f'if "${{{stage}cut}} > 0" then &',
            f"  \"print '# cut {stage} ${{n}}' append {DISCHARGE} screen no\" "
            f'"jump SELF end_{stage}"',
        )

    def settle(self) -> None:
        t, geo = self.t, self.geo
        t_min = 2.0 * math.sqrt(2.0 * geo.wall_top / t.gravity)
        # settle_ke N m g R with N m the fill's mass (engine.hopper.driver.HopperRun)
        bound = t.settle_ke * float(self.masses.sum()) * t.gravity * t.radius
        over = math.ceil(t.max_settle_time / self.dt)
        self.add(
            "",
            "# ------------------------------------------------------------------ settling",
            "# the fill settles behind the closed gate: at least two free-fall times from the",
            "# walls' top, then until its kinetic energy is below settle_ke N m g R",
            f'print "# begin settle ${{n}}" append {DISCHARGE} screen no',
        )
        self.row(0)
        dt = _num(self.dt)
        cut_def, cut = self.cut("settle", "0")
        self.add(
            *cut_def,
            f"variable sdone equal (v_n*{dt}>={_num(t_min)})*(v_kin<{_num(bound)})",
            f"variable sover equal v_n>={over}",
            "label loop_settle",
            'if "${sdone} > 0" then "jump SELF end_settle"',
            'if "${sover} > 0" then &',
            f"  \"print '# error settle ${{n}} ${{kin}}' append {DISCHARGE} screen no\" "
            '"jump SELF finish"',
            *cut,
            f"run {self.S} pre no post no",
        )
        self.row(0)
        self.add("jump SELF loop_settle", "label end_settle")
        self.add(f'print "# end settle ${{n}}" append {DISCHARGE} screen no')
        self.dump("settled")

    def discharge(self) -> None:
        t = self.t
        speed = t.resolved_gate_speed
        gate_steps = self.gate_steps
        wait = t.arch_wait * t.free_fall_time
        k = max(1, math.ceil(wait / t.output_interval))  # samples in a stop window
        pm = float(self.masses.min())  # the lightest particle's mass [kg]
        self.add(
            "",
            "# ------------------------------------------------------------------ discharge",
            f"# the gate moves down at gate_speed = {speed!r} m/s for {gate_steps} steps",
            "# (below the catch floor), then stops; a sample every output_interval until the",
            "# hopper is empty, the flow has stopped (the mass discharged over a window of",
            "# arch_wait free-fall times below arch_fraction of the fastest window's, or below",
            "# a particle's mass), or max_discharge_time",
            "variable topen equal ${n}",
            f'print "# begin discharge ${{n}}" append {DISCHARGE} screen no',
            "fix movegate all move/mesh mesh gate linear/variable v_zero v_zero v_vgate",
            "run 0",
        )
        self.row(1)
        dt = _num(self.dt)
        cut_def, cut = self.cut("discharge", "v_topen")
        self.add(
            *cut_def,
            "variable ns equal 0",
            f"variable dumpnow equal (v_ns-floor(v_ns/{self.dump_every})*{self.dump_every})==0",
            "variable wcount equal 0",
            "variable wmass equal ${mout}",
            "variable wfast equal 0.0",
            "variable dempty equal v_mrest<=0",
            f"variable dtime equal (v_n-v_topen)*{dt}>={_num(t.max_discharge_time)}",
            "variable wmoved equal v_mout-v_wmass",
            f"variable wstop equal (v_wmoved<{_num(pm)})"
            f"+(v_wmoved<{_num(t.arch_fraction)}*v_wfast)",
            "variable wfaster equal v_wmoved>v_wfast",
            "# after each sample, as demscale reads it: emptied, then the flow stopped (at the",
            f"# end of a window of {k} samples), then max_discharge_time",
            "label loop_discharge",
            'if "${dempty} > 0" then "jump SELF end_discharge"',
            f'if "${{wcount}} >= {k} && ${{wstop}} > 0" then &',
            f"  \"print '# stopped ${{n}}' append {DISCHARGE} screen no\" "
            '"jump SELF end_discharge"',
            f'if "${{wcount}} >= {k} && ${{wfaster}} > 0" then "variable wfast equal ${{wmoved}}"',
            f'if "${{wcount}} >= {k}" then "variable wmass equal ${{mout}}" '
            '"variable wcount equal 0"',
            'if "${dtime} > 0" then "jump SELF end_discharge"',
            'if "${dumpnow} > 0" then "jump SELF dump_discharge"',
            "label run_discharge",
            *cut,
            f"run {self.S} pre no post no",
        )
        self.row(1)
        self.add(
            "variable wcount equal ${wcount}+1",
            "variable ns equal ${ns}+1",
            "jump SELF loop_discharge",
            "label dump_discharge",
        )
        self.dump()
        self.add(
            "jump SELF run_discharge",
            "label end_discharge",
            f'print "# end discharge ${{n}}" append {DISCHARGE} screen no',
        )


def hopper_deck(
    test,
    skin: float | None = None,
    dump_every: int = DUMP_EVERY,
    max_steps: int | None = None,
    geometry=None,
) -> str:
    """The LIGGGHTS 3.8 input deck of ``test`` (an :class:`engine.HopperTest`; module
    docstring): ``skin`` the Verlet skin [m] (default :data:`SKIN_RADII` largest radii),
    a particle dump every ``dump_every`` samples of the discharge, ``max_steps`` a bound on
    each stage's steps (None: ``max_settle_time`` and ``max_discharge_time``; a smaller one
    makes a short check of the deck). Raises :class:`engine.ParameterError` naming the
    field for what it cannot express."""
    check_laws(test, "HopperTest")
    geo = geometry or _geometry(test)
    rmax = float(np.max(geo.scene.radii))
    if skin is None:
        skin = SKIN_RADII * rmax
    if not (isinstance(skin, (int, float)) and math.isfinite(skin) and skin > 0):
        raise ParameterError("skin", skin, "a length > 0 m")
    if not (isinstance(dump_every, int) and not isinstance(dump_every, bool) and dump_every >= 1):
        raise ParameterError("dump_every", dump_every, "a whole number of samples >= 1")
    if max_steps is not None and not (
        isinstance(max_steps, int) and not isinstance(max_steps, bool) and max_steps >= 1
    ):
        raise ParameterError("max_steps", max_steps, "a whole number of steps >= 1, or None")
    return _HopperDeck(test, geo, skin, dump_every, max_steps).build()


def write_hopper_deck(
    test,
    directory,
    skin: float | None = None,
    dump_every: int = DUMP_EVERY,
    max_steps: int | None = None,
) -> Path:
    """Write the deck folder of ``test`` (an :class:`engine.HopperTest`) into ``directory``
    (created): ``in.hopper``, the fill ``fill.data``, the walls' and the gate's STL files
    and the test as ``test.json``. Returns the deck's path. LIGGGHTS runs it there,
    unmodified: ``liggghts -in in.hopper`` (its output: ``discharge.txt``, ``dump/``,
    ``log.liggghts``: :func:`read_discharge` reads the first)."""
    geo = _geometry(test)
    text = hopper_deck(test, skin, dump_every, max_steps, geo)
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    scene = geo.scene
    meshes = deck_meshes(test, geo)
    for name, i in zip(_wall_files(geo), geo.wall_meshes, strict=True):
        meshes[i].to_stl(out / name, solid=name.removesuffix(".stl"))
    meshes[geo.gate_mesh].to_stl(out / GATE, solid="gate")
    (out / FILL).write_text(fill_data(test, scene.positions, scene.radii, deck_box(geo)))
    (out / HOPPER_TEST).write_text(json.dumps(test.to_dict(), indent=1) + "\n")
    (out / HOPPER_DECK).write_text(text)
    for stale in [out / DISCHARGE, out / HOPPER_LOG, *out.glob(f"{DUMP_DIR}/*.dump")]:
        stale.unlink(missing_ok=True)
    return out / HOPPER_DECK


def read_discharge(directory) -> dict[str, np.ndarray]:
    """The sample lines of a deck folder's :data:`DISCHARGE` as columns
    (:data:`DISCHARGE_COLUMNS`), and ``"events"``: its ``#`` marks (``begin settle``,
    ``end discharge``, ``stopped``, ``error`` ..., each with its step) in order."""
    rows, events = [], []
    for line in (Path(directory) / DISCHARGE).read_text().splitlines():
        if line.startswith("#"):
            events.append(line[1:].strip())
        elif line.strip():
            rows.append([float(v) for v in line.split()])
    a = np.array(rows, dtype=float).reshape(-1, len(DISCHARGE_COLUMNS))
    out = {k: a[:, i] for i, k in enumerate(DISCHARGE_COLUMNS)}
    out["events"] = np.array(events, dtype=object)
    return out


__all__ = [
    "DISCHARGE",
    "DISCHARGE_COLUMNS",
    "FILL",
    "GATE",
    "HOPPER_DECK",
    "hopper_deck",
    "hopper_differences",
    "read_discharge",
    "write_hopper_deck",
]
