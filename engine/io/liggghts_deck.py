"""A uniaxial test, whole, as a LIGGGHTS 3.8 input deck (docs/LIGGGHTS_DECK.md).

:func:`write_deck` writes a folder that LIGGGHTS runs unmodified (``liggghts -in
in.demscale`` there): the deck, demscale's own poured cloud as a LAMMPS data file (the
packing :meth:`engine.UniaxialTest.initial_packing` places, so both codes start from the
same spheres), the two platen meshes (STL) and the test's JSON (what
:mod:`engine.io.liggghts_read` reads the output back with). The deck runs the stages of
:mod:`engine.uniaxial.driver` with their targets and stopping rules, one curve sample every
``output_interval``, as a loop of ``run`` commands with ``if`` checks between them:

=================  ==================================================================
demscale           LIGGGHTS 3.8
=================  ==================================================================
cell, periodic     ``boundary p p f``, the box (0, Lx) x (0, Ly), z from below the
x and y            bottom platen to above the pour column
the poured cloud   ``read_data packing.data`` (id, type 1, diameter, density, x, y, z)
pair law           ``pair_style gran model edinburgh/stiffness`` (bilinear and EEPA) or
                   ``model hertz``: what the law's mapping declares (engine.contact.export)
platens            Hertz-Mindlin walls of atom type 2 (E, nu of ``wall_material``;
                   the particles' E, nu from ``wall_law``): the bottom a
                   ``primitive zplane 0`` with ``store_force``, the top during the fill a
                   primitive plane at the pour column's top + 4 R, from the
                   pre-compression on an STL plate of the cell's size
                   (``mesh/surface/stress``, moved by ``move/mesh linear/variable``),
                   after the release a plate three cells wide
fill               run until the free-fall time has passed and the kinetic energy is
                   below ``settle_ke N m g R`` (``pour_speed``: ``velocity set`` caps
                   every faster particle after each sample)
pre-compression,   the plate placed 0.05 R above the highest sphere, moved down at
consolidation      ``platen_speed`` until its stress reaches each target
hold               (``hold_time`` set) the plate stopped for ``hold_time``, then until the
                   kinetic energy is below ``settle_ke N m g R`` (``hold_quiet``: at every
                   sample for that long, the step of the last louder one kept in a variable)
unloading          moved up until the stress is below ``unloaded_stress`` sigma_c
release            ``change_box all boundary f f f`` (contacts across the faces go), the
                   box widened, the wide plate put where the plate was; settle or
                   ``release_time``
unconfined         moved down until demscale's failure detector fires (its peak and
                   drop replayed in LIGGGHTS variables) or ``max_unconfined_strain``
stage bound        ``max_stage_time``: the deck writes an ``error`` line and stops
=================  ==================================================================

After every sample the deck appends one line to ``curves.txt`` (:data:`COLUMNS`: step, the
top platen's height, the platen forces [N], kinetic energies [J], contacts, the interior
slab's solid volume [m^3], particle and contact counts, the pair virial [N m] and the
platen levers [m] of demscale's vertical virial), and marks each stage's begin and end;
each stage's end writes the particles (``stage_<name>.dump``: id x y z radius). The reader
turns them into demscale's curves with demscale's own formulas.

What the deck cannot make LIGGGHTS do the same way is said in its comments
(:func:`differences`): those the pair law's mapping declares (for the bilinear and EEPA laws
:func:`engine.io.liggghts.differences`: tangential stiffness K1, Coulomb cap mu |F_n|,
damping for n != 1, force clipping without adhesion; then the plastic reload, rolling
friction and the history across periodic faces) and the platen differences of the deck
itself. The deck asks the pair and wall laws for their mappings only, and tests no law's
type. What it cannot express at all raises
:class:`engine.ParameterError` naming the field (:func:`check_exportable`).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..core.errors import ParameterError
from ..simulation.packing import sphere_volume
from .liggghts import mapping

#: Files of a deck folder.
DECK = "in.demscale"
DATA = "packing.data"
PLATE = "plate.stl"
PLATE_WIDE = "plate_wide.stl"
TEST = "test.json"
#: What the deck writes there.
CURVES = "curves.txt"
LOG = "log.liggghts"
STAGE_DUMP = "stage_{}.dump"

#: The stages' codes in ``curves.txt`` (a line's first value is its stage's index here):
#: engine.uniaxial.driver.STAGES, with the hold stage last so that a file written before it
#: reads the same (the run order is engine.uniaxial.driver.stages_of).
STAGES = (
    "fill",
    "pre_compression",
    "consolidation",
    "unloading",
    "release",
    "unconfined",
    "hold",
)

#: The columns of a sample line of ``curves.txt``, with units: the stage's index in
#: :data:`STAGES`, the step, the top platen's height (the bottom one is at z = 0) [m], the z
#: force on the top platen and the z force of the bottom platen on the particles [N],
#: translational and rotational kinetic energy [J], the particle-particle contacts counted
#: at both ends (LIGGGHTS ``contact/atom``, summed), the solid volume inside the interior
#: slab [m^3], the particles whose centres lie in it, their contacts and the sum of their
#: per-atom pair stress zz [N m] (the interior virial stress, minus), the sums over
#: particles of LIGGGHTS' per-atom pair stress xx, yy, zz [N m] (minus the pair virial),
#: and for each platen the sum of the levers (radius less overlap) of the particles
#: touching it [m] and their number.
COLUMNS = {
    "stage": "1",
    "step": "1",
    "ztop": "m",
    "ftop": "N",
    "fbot": "N",
    "ke_trans": "J",
    "ke_rot": "J",
    "contacts": "1",
    "slab_solid": "m^3",
    "interior_n": "1",
    "interior_contacts": "1",
    "interior_stress_zz": "N m",
    "stress_xx": "N m",
    "stress_yy": "N m",
    "stress_zz": "N m",
    "lever_bottom": "m",
    "touch_bottom": "1",
    "lever_top": "m",
    "touch_top": "1",
}

#: The deck's variable behind each column of :data:`COLUMNS` after the stage's index.
ROW_VARIABLES = (
    "n",
    "ztop",
    "ftop",
    "fbot",
    "ket",
    "ker",
    "ncon",
    "slab",
    "nin",
    "cin",
    "szi",
    "sxx",
    "syy",
    "szz",
    "lbot",
    "nbot",
    "ltop",
    "ntop",
)

#: Verlet skin in radii of the largest particle: a list is rebuilt when a particle has moved
#: a quarter radius.
SKIN_RADII = 0.5
#: The plate after the release spans this many cells along x and y, centred on the cell,
#: so that a sample spreading sideways stays under it (demscale's platens are unbounded).
WIDE = 3
#: Gap between the highest sphere and the top plate when the pre-compression begins, in
#: radii (engine.uniaxial.driver: bed top + 0.05 R).
PLACE_GAP = 0.05


def _num(x: float) -> str:
    """A float as LIGGGHTS reads it back to the same double."""
    return repr(float(x))


def _pair(test, owner: str = "UniaxialTest"):
    """The pair law's LIGGGHTS mapping (engine.contact.export), refusals at
    ``<owner>.pair_law``."""
    return mapping(test.pair_law, f"{owner}.pair_law", f"{owner}.pair_law")


def _wall(test, owner: str = "UniaxialTest"):
    """The wall law's LIGGGHTS mapping, refusals at ``<owner>.wall_law``."""
    return mapping(test.wall_law, f"{owner}.wall_law", f"{owner}.wall_law")


#: Protocol fields the deck cannot write, at the value it can: a platen speed held to an
#: inertial number is recomputed after every sample from the stress and, past the
#: unconfined peak, from a running smoothed strength curve that LIGGGHTS 3.8's input
#: language (no arrays) cannot keep; the deck moves the platen at ``platen_speed``.
_PROTOCOL_DEFAULTS = {"inertial_number": None}


def check_exportable(test) -> None:
    """Raise :class:`engine.ParameterError` naming the field of ``test`` (an
    :class:`engine.UniaxialTest`) that a LIGGGHTS 3.8 deck cannot express: a pair or wall
    law without a LIGGGHTS mapping (engine.contact.export; the bilinear, EEPA and
    Hertz-Mindlin laws have one), what the law's mapping refuses (an adhesive branch,
    kadh > 0, with n or chi != 1; with n = chi = 1 it is written on LIGGGHTS' ``fixKc on``
    path), a per-atom-type property of the pair law (a Hertz law's E, nu) that differs from
    the wall law's (LIGGGHTS has one value per atom type for pairs and walls alike), or a
    platen speed that is not constant."""
    check_laws(test)
    for name, default in _PROTOCOL_DEFAULTS.items():
        value = getattr(test, name, default)
        if value != default:
            raise ParameterError(
                f"UniaxialTest.{name}",
                value,
                f"{default} (a constant platen speed) to export to LIGGGHTS",
                "the deck moves the platen at platen_speed; a speed held to an inertial "
                "number is not written",
            )


def check_laws(test, owner: str = "UniaxialTest") -> None:
    """Raise :class:`engine.ParameterError` naming ``<owner>.pair_law`` or
    ``<owner>.wall_law`` where a deck of ``test`` cannot write its laws: no LIGGGHTS mapping,
    the mapping's own refusals, or a per-atom-type property of the pair law that differs from
    the wall law's (:func:`check_exportable`)."""
    pair, wall = _pair(test, owner), _wall(test, owner)
    walls = {p.name: p for p in wall.atom_type}
    for p in pair.atom_type:
        q = walls.get(p.name)
        if q is None or q.value != p.value:
            shown = ", ".join(f"{w.field} = {w.value:g}{_unit(w)}" for w in wall.atom_type)
            wanted = " and ".join(f"{w.field} = {w.value:g}{_unit(w)}" for w in pair.atom_type)
            raise ParameterError(
                f"{owner}.wall_law.{p.field}",
                shown or "none",
                f"the pair law's {wanted}",
                "LIGGGHTS gives the particles' atom type one "
                + " and ".join(w.name for w in pair.atom_type)
                + " for pairs and walls alike",
            )


def _unit(p) -> str:
    return f" {p.unit}" if p.unit not in ("", "1") else ""


def differences(test) -> list[str]:
    """What LIGGGHTS does differently from demscale in the deck of ``test``: the pair law's
    in a deck (its mapping's, engine.contact.export), then the deck's own (platens), then
    the pair law's across the periodic faces, then the fill's speed cap."""
    pair = _pair(test)
    out = list(pair.deck_differences)
    out.append(
        "platens: the top one is an STL plate (the cell's size, three cells wide after the "
        "release; contacts with its edges are sphere-edge contacts), the bottom one a "
        "primitive plane; LIGGGHTS caps platen friction at mu |F_n| with damping, demscale "
        "at mu times the elastic Hertz force"
    )
    out += pair.periodic_differences
    if test.pour_speed is not None:
        out.append(
            "the fill's speed cap is applied with the same rule, after each sample, through "
            "velocity set"
        )
    return out


def deck_head(
    log: str, boundary: str, data: str, skin: float, materials: list[str], dt: float, gravity: float
) -> list[str]:
    """The lines a deck opens with (the uniaxial deck's and the hopper deck's): its ``log``
    file, SI units, granular atoms, the ``boundary`` line, the ``data`` file, a binned
    neighbour list of ``skin`` [m] rebuilt as needed, the ``materials`` lines, the time step
    ``dt`` [s], ``gravity`` [m/s^2] along -z and the NVE integrator of spheres."""
    return [
        f"log {log}",
        "echo none",
        "units si",
        "atom_style granular",
        "atom_modify map array sort 0 0.0",
        boundary,
        "newton off",
        "communicate single vel yes",
        "processors * * 1",
        f"read_data {data}",
        "hard_particles yes",
        f"neighbor {_num(skin)} bin",
        "neigh_modify delay 0",
        "",
        *materials,
        "",
        f"timestep {_num(dt)}",
        f"fix grav all gravity {_num(gravity)} vector 0.0 0.0 -1.0",
        "fix integr all nve/sphere",
    ]


# ----------------------------------------------------------------------------- the files
def granular_data(
    title: str, positions: np.ndarray, radii: np.ndarray, density: float, bounds
) -> str:
    """Spheres as a LAMMPS ``atom_style granular`` data file headed ``title``: two atom types
    (1 the particles, 2 the walls' material), the box ``bounds`` = ((xlo, xhi), (ylo, yhi),
    (zlo, zhi)) [m], one line per sphere (id = demscale's index + 1, type, diameter [m],
    ``density`` [kg/m^3], x, y, z [m]). The uniaxial deck's and the hopper deck's."""
    lines = [
        title,
        "",
        f"{len(radii)} atoms",
        "2 atom types",
        "",
        *(f"{_num(lo)} {_num(hi)} {a}lo {a}hi" for (lo, hi), a in zip(bounds, "xyz")),
        "",
        "Atoms",
        "",
    ]
    rho = _num(density)
    lines += [
        f"{i + 1} 1 {_num(2 * r)} {rho} {_num(x)} {_num(y)} {_num(z)}"
        for i, (r, (x, y, z)) in enumerate(zip(radii, positions))
    ]
    return "\n".join(lines) + "\n"


def data_file(test, positions: np.ndarray, radii: np.ndarray) -> str:
    """The poured cloud as a LAMMPS data file (:func:`granular_data`) in the box of the
    deck, atom type 2 the platens' material."""
    lo, hi = box(test)
    title = "LAMMPS data file of a demscale uniaxial test (engine.io.liggghts_deck)"
    return granular_data(title, positions, radii, test.density, tuple(zip(lo, hi)))


def plate_stl(x0: float, y0: float, x1: float, y1: float, name: str = "plate") -> str:
    """A flat rectangle [x0, x1] x [y0, y1] at z = 0 [m] as two ASCII STL facets."""
    corners = [(x0, y0), (x1, y1), (x1, y0), (x0, y0), (x0, y1), (x1, y1)]
    out = [f"solid {name}"]
    for k in (0, 3):
        out += ["  facet normal 0 0 -1", "    outer loop"]
        out += [f"      vertex {_num(x)} {_num(y)} 0" for x, y in corners[k : k + 3]]
        out += ["    endloop", "  endfacet"]
    out.append(f"endsolid {name}")
    return "\n".join(out) + "\n"


def box(test) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """The LIGGGHTS box (lo, hi) [m]: the periodic cell in x and y, in z from two largest
    radii below the bottom platen to four above the fill's top wall."""
    lx, ly, _ = test.pour_region
    rmax = test.radius * (1 + test.polydispersity)
    return (0.0, 0.0, -2 * rmax), (lx, ly, fill_top(test) + 4 * rmax)


def fill_top(test) -> float:
    """Height of the top wall during the fill [m] (engine.UniaxialTest.scene)."""
    return test.pour_region[2] + 4 * test.radius


def resolved_dt(test) -> float:
    """The time step demscale runs ``test`` with [s]."""
    return float(test.resolved_dt())


def sample_steps(test) -> int:
    """Steps between two curve samples (engine.uniaxial.driver)."""
    return max(1, round(test.output_interval / resolved_dt(test)))


def max_steps(test) -> int:
    """Steps a stage may take before it fails (``max_stage_time``)."""
    return max(1, round(test.max_stage_time / resolved_dt(test)))


def fall_time(test) -> float:
    """The fill's shortest duration [s] (engine.uniaxial.driver: the free fall over the
    cell's height, or the capped pour's column over ``pour_speed``)."""
    t = math.sqrt(2 * test.cell[2] / test.gravity)
    if test.pour_speed is not None:
        t = max(t, test.pour_height / test.pour_speed)
    return t


def settle_energy(test) -> float:
    """The kinetic energy below which a stage has settled [J]: settle_ke N m g R."""
    m = float(test.density * sphere_volume(test.radius))
    return test.settle_ke * test.n_particles * m * test.gravity * test.radius


def release_times(test) -> tuple[float, float]:
    """The release's shortest and longest duration [s] (engine.uniaxial.driver)."""
    t_min = 5 * math.sqrt(2 * test.radius / test.gravity)
    return t_min, max(t_min, test.release_time)


# ----------------------------------------------------------------------------- the deck
def _materials(test, owner: str = "UniaxialTest") -> list[str]:
    """``fix property/global`` lines for two atom types (1 particles, 2 platens or walls) and
    the pair style: what the pair and wall laws' mappings declare (engine.contact.export),
    the walls' per-atom-type values from ``wall_material``."""
    pair, wall = _pair(test, owner), _wall(test, owner)
    platen = {p.name: p.value for p in test.wall_material.liggghts_atom_type()}

    def two(pp: float, pw: float) -> str:
        return f"peratomtypepair 2 {_num(pp)} {_num(pw)} {_num(pw)} {_num(pw)}"

    lines = [
        "# materials: atom type 1 the particles, 2 the platens (Hertz-Mindlin: E, nu of",
        "# both sides; restitution, friction and rolling friction per type pair)",
    ]
    k = 0
    for p in wall.atom_type:
        k += 1
        lines.append(
            f"fix m{k} all property/global {p.name} peratomtype {_num(p.value)} "
            f"{_num(platen[p.name])}"
        )
    for p, w in zip(pair.coefficients, wall.coefficients):
        k += 1
        lines.append(f"fix m{k} all property/global {p.name} " + two(p.value, w.value))
    if pair.deck_summary:
        lines.append(f"# {pair.deck_summary}")
    for p in pair.properties:
        k += 1
        how = f"scalar {_num(p.value)}" if p.scalar else two(p.value, p.value)
        lines.append(f"fix m{k} all property/global {p.name} {how}")
    roll = " rolling_friction cdt" if pair.rolling else ""
    lines.append(f"pair_style gran model {pair.model} tangential history{roll}{pair.settings}")
    lines.append("pair_coeff * *")
    return lines


def _wall_model(test, owner: str = "UniaxialTest") -> str:
    wall = _wall(test, owner)
    roll = " rolling_friction cdt" if wall.rolling else ""
    return f"wall/gran model {wall.model} tangential history{roll}{wall.settings}"


def _min(a: str, b: str) -> str:
    """min(a, b) as a LIGGGHTS formula (it has no min function)."""
    return f"(({a})*(({a})<({b}))+({b})*(({a})>=({b})))"


def _clip(x: str, r: str) -> str:
    """x clipped to [-r, r] as a LIGGGHTS atom formula."""
    return f"({x}+(({x})<-({r}))*(-({r})-({x}))+(({x})>({r}))*(({r})-({x})))"


class _Deck:
    """Builds the deck's lines for one test."""

    def __init__(self, test, skin: float, rmax: float):
        self.t = test
        self.skin = skin
        self.lines: list[str] = []
        self.dt = resolved_dt(test)
        self.area = test.cell[0] * test.cell[1]
        self.S = sample_steps(test)
        self.max_steps = max_steps(test)
        self.rmax = rmax  # the largest radius of the packing [m], as demscale's interior

    def add(self, *lines: str) -> None:
        self.lines.extend(lines)

    def row(self, stage: str) -> None:
        """One sample line of curves.txt."""
        values = " ".join("${" + v + "}" for v in ROW_VARIABLES)
        self.add(f'print "{STAGES.index(stage)} {values}" append {CURVES} screen no')

    def velocity(self, v: float) -> None:
        """The top platen moves at v [m/s] from now on: its height so far is frozen into
        zbase at this step, and the height formula goes on from there."""
        self.add(
            "variable zbase equal ${ztop}",
            "variable sbase equal ${n}",
            f"variable vplaten equal {_num(v)}",
        )

    def begin(self, stage: str) -> None:
        self.add("", f"# ---------------------------------------------------------- {stage}")

    def start_stage(self, stage: str, h0: str = "${gap}") -> None:
        """The stage's start step and reference height (immediate values), its begin mark
        and its first sample (computes current: the run before left them so)."""
        self.add(f"variable h0 equal {h0}", "variable t0 equal ${n}")
        self.add(
            f'print "# begin {stage} ${{t0}} ${{h0}}" append {CURVES} screen no',
        )
        self.row(stage)

    def loop(self, stage: str, done: str, after_run: tuple[str, ...] = ()) -> None:
        """The stage's loop: until ``done`` (an equal-style formula, 1 when the stage is
        over) holds for the last sample: the bound on its steps, one sample's run, the
        sample."""
        self.add(
            f"variable done equal {done}",
            f"variable over equal (v_n-v_t0)>={self.max_steps}",
            f"label loop_{stage}",
            f'if "${{done}} > 0" then "jump SELF end_{stage}"',
            'if "${over} > 0" then &',
            f"  \"print '# error {stage} ${{n}} ${{stop}} ${{gap}} ${{kin}}' append {CURVES} "
            'screen no" "jump SELF finish"',
            f"run {self.S} pre no post no",
            *after_run,
        )
        self.row(stage)
        self.add(f"jump SELF loop_{stage}", f"label end_{stage}")

    def end(self, stage: str) -> None:
        self.add(
            f"write_dump all custom {STAGE_DUMP.format(stage)} id x y z radius modify sort id "
            'format "%d %.17g %.17g %.17g %.17g"',
            f'print "# end {stage} ${{n}}" append {CURVES} screen no',
        )

    def computes(self, fill_wall: bool) -> list[str]:
        """Every compute a sample reads."""
        return [
            "c_fbsum",
            *(["c_ffsum"] if fill_wall else []),
            "c_ker",
            "c_ncn",
            "c_slabv",
            "c_insum[1]",
            "c_insum[2]",
            "c_insum[3]",
            "c_sab[1]",
            "c_sab[2]",
            "c_sab[3]",
            "c_lev[1]",
            "c_lev[2]",
            "c_lev[3]",
            "c_lev[4]",
            "c_zmax",
        ]

    def sampler(self, fill_wall: bool, extra=()) -> list[str]:
        """A fix that invokes every compute a sample reads on every run's last step:
        LIGGGHTS lets a variable read a compute between runs only when something invoked it
        on that step, and tallies the pair virial only on steps something asked for it."""
        c = " ".join([*self.computes(fill_wall), *extra])
        every = self.S if not extra else self.probe_every
        return [f"fix sample all ave/time {every} 1 {every} {c}"]

    def setup_run(self, fill_wall: bool, extra=()) -> list[str]:
        """A set-up run of no steps (new fixes, a new box) with the computes in the thermo
        output, which invokes them there, then the thermo output back to the step alone."""
        return [
            "thermo_style custom step atoms ke " + " ".join([*self.computes(fill_wall), *extra]),
            "run 0",
            "thermo_style custom step atoms ke",
            "thermo_modify norm no lost error",
        ]

    # ------------------------------------------------------------------- sections
    def build(self) -> str:
        self.header()
        self.add(
            f'print "# demscale LIGGGHTS output: {" ".join(COLUMNS)}" file {CURVES} screen no',
        )
        self.fill()
        self.compression()
        self.release()
        self.unconfined()
        self.add("", "label finish", f'print "# done ${{n}}" append {CURVES} screen no')
        return "\n".join(self.lines) + "\n"

    def header(self, periodic: bool = True) -> None:
        """Everything before the stages: units, box, packing, materials, walls, what a
        sample reads; ``periodic`` False: a box walled in x and y instead (a probe's)."""
        t = self.t
        self.add(
            "# demscale uniaxial test as a LIGGGHTS 3.8 deck (engine.io.liggghts_deck),",
            "# docs/LIGGGHTS_DECK.md. Run it in this folder: liggghts -in in.demscale",
            f"# {t.n_particles} particles, R = {t.radius!r} m, cell {t.cell!r} m, seed {t.seed},",
            f"# pair law {_pair(t).law}, dt = {self.dt!r} s, a sample every {self.S} steps;",
            "# every parameter of the test is in test.json. LIGGGHTS does differently:",
        )
        for d in differences(t):
            self.add(f"#   - {d}")
        self.add(
            "",
            *deck_head(
                LOG,
                "boundary p p f" if periodic else "boundary f f f",
                DATA,
                self.skin,
                _materials(t),
                self.dt,
                t.gravity,
            ),
            f"fix wallb all {_wall_model(t)} primitive type 2 zplane 0.0 store_force yes",
            f"fix wallf all {_wall_model(t)} primitive type 2 zplane {_num(fill_top(t))} "
            "store_force yes",
            *([] if periodic else self.side_walls()),
            "",
            "# Variables. LIGGGHTS 3.8 redefines an equal-style variable by deleting it and",
            "# appending it anew, which shifts every later variable's index, and fixes and",
            "# computes keep the index they found at a run's set-up (runs here skip it): so the",
            "# variables a fix or compute reads come first and are never redefined, and those",
            "# the stages redefine come last.",
            "variable zero equal 0.0",
            "variable vmesh equal v_vplaten",
            *self.pour_variables(),
            "variable ua atom " + _clip("v_lo-z", "r"),
            "variable ub atom " + _clip("v_hi-z", "r"),
            "variable vs atom PI*(r*r*(v_ub-v_ua)-(v_ub*v_ub*v_ub-v_ua*v_ua*v_ua)/3.0)",
            "variable vsp atom v_vs*(v_vs>0)",
            "variable inside atom (z>=v_lo)*(z<=v_hi)",
            "compute cn all contact/atom",
            "variable cinside atom v_inside*c_cn",
            "compute sa all stress/atom pair",
            "variable szin atom v_inside*c_sa[3]",
            "variable tb atom z<r",
            "variable lb atom (z<r)*z",
            "variable tt atom (v_ztop-z)<r",
            "variable lt atom ((v_ztop-z)<r)*(v_ztop-z)",
            "variable zr atom z+r",
            "# what a sample reads",
            "compute fbsum all reduce sum f_force_wallb[3]",
            "compute ffsum all reduce sum f_force_wallf[3]",
            "compute ker all erotate/sphere",
            "compute ncn all reduce sum c_cn",
            "# the interior slab (engine.uniaxial.measures.interior_measures)",
            "compute slabv all reduce sum v_vsp",
            "compute insum all reduce sum v_inside v_cinside v_szin",
            "# pair virial, minus (engine.Simulation.pair_stress)",
            "compute sab all reduce sum c_sa[1] c_sa[2] c_sa[3]",
            "# platen levers (engine.kernel.virial.platen_levers)",
            "compute lev all reduce sum v_lb v_tb v_lt v_tt",
            "compute zmax all reduce max v_zr",
            "variable n equal step",
            f"variable ztop equal v_zbase+v_vplaten*(step-v_sbase)*{_num(self.dt)}",
            "variable gap equal v_ztop",
            "variable fbot equal c_fbsum",
            f"variable stop equal v_ftop/{_num(self.area)}",
            "variable ket equal ke(all)",
            "variable ker equal c_ker",
            "variable kin equal v_ket+v_ker",
            "variable ncon equal c_ncn",
            f"variable mg equal {_min(_num(t.margin), f'0.5*v_gap-{_num(self.rmax)}')}",
            "variable lo equal v_mg*(v_mg>0)",
            "variable hi equal v_gap-v_lo",
            "variable slab equal c_slabv",
            "variable nin equal c_insum[1]",
            "variable cin equal c_insum[2]",
            "variable szi equal c_insum[3]",
            f"variable sin equal -v_szi/({_num(self.area)}*(v_hi-v_lo)+(v_hi<=v_lo))*(v_hi>v_lo)",
            f"variable sdet equal v_{'sin' if t.strength_from == 'interior' else 'stop'}",
            "variable sxx equal c_sab[1]",
            "variable syy equal c_sab[2]",
            "variable szz equal c_sab[3]",
            "variable lbot equal c_lev[1]",
            "variable nbot equal c_lev[2]",
            "variable ltop equal c_lev[3]",
            "variable ntop equal c_lev[4]",
            "variable strain equal (v_h0-v_gap)/v_h0",
            "# redefined by the stages (the top platen's motion, the stage's start)",
            f"variable zbase equal {_num(fill_top(t))}",
            "variable sbase equal 0",
            "variable vplaten equal 0.0",
            "variable ftop equal -c_ffsum",
            "",
            *self.sampler(fill_wall=True),
            "thermo_style custom step atoms ke",
            "thermo_modify norm no lost error",
            f"thermo {self.S}",
        )

    def side_walls(self) -> list[str]:
        """Primitive planes on the cell's four side faces (a probe without periodicity)."""
        lx, ly = self.t.cell[0], self.t.cell[1]
        return [
            f"fix {name} all {_wall_model(self.t)} primitive type 2 {axis}plane {_num(at)} "
            "store_force yes"
            for name, axis, at in (
                ("wx0", "x", 0.0),
                ("wx1", "x", lx),
                ("wy0", "y", 0.0),
                ("wy1", "y", ly),
            )
        ]

    def probe(self, steps: int, every: int, periodic: bool) -> str:
        """A deck that runs ``steps`` steps from the packing at rest with every force on, no
        platen but the bottom one and the fill's top wall, and writes after every ``every``
        steps a sample line (:data:`COLUMNS`) and the sums over the particles of the total
        force and of the walls' forces [N] (``probe.txt``): the pair forces' sum, their
        difference less gravity, is zero for a law that conserves momentum."""
        self.header(periodic)
        walls = ["wallb", "wallf"] + ([] if periodic else ["wx0", "wx1", "wy0", "wy1"])
        parts = " ".join(f"f_force_{w}[{k}]" for k in (1, 2, 3) for w in walls)
        self.add(
            "compute fat all reduce sum fx fy fz",
            f"compute fwall all reduce sum {parts}",
        )
        n = len(walls)
        sums = [f"c_fwall[{k * n + w + 1}]" for k in range(3) for w in range(n)]
        for k, axis in enumerate("xyz"):
            self.add(f"variable fw{axis} equal " + "+".join(sums[k * n : (k + 1) * n]))
        self.add(
            "variable fax equal c_fat[1]",
            "variable fay equal c_fat[2]",
            "variable faz equal c_fat[3]",
        )
        extra = ["c_fat[1]", "c_fat[2]", "c_fat[3]", *[f"c_fwall[{i + 1}]" for i in range(3 * n)]]
        self.probe_extra = extra
        names = (*ROW_VARIABLES, "fax", "fay", "faz", "fwx", "fwy", "fwz")
        row = " ".join("${" + v + "}" for v in names)
        line = f'print "0 {row}" append probe.txt screen no'
        self.add(
            *self.sampler(fill_wall=True, extra=extra),
            "thermo_style custom step atoms ke",
            "thermo_modify norm no lost error",
            f"thermo {every}",
            f"variable h0 equal {_num(fill_top(self.t))}",
            "variable t0 equal 0",
            f'print "# probe: {" ".join(COLUMNS)} sum_fx sum_fy sum_fz wall_fx wall_fy wall_fz"'
            " file probe.txt screen no",
            *self.setup_run(fill_wall=True, extra=extra),
            line,
        )
        for _ in range(steps // every):
            self.add(f"run {every} pre no post no", line)
        return "\n".join(self.lines) + "\n"

    def pour_variables(self) -> list[str]:
        """The capped pour's velocity formulas: every particle faster than pour_speed
        slowed to it (engine.uniaxial.driver: after each sample of the fill)."""
        if self.t.pour_speed is None:
            return []
        cap = _num(self.t.pour_speed)
        return [
            "variable vm atom sqrt(vx*vx+vy*vy+vz*vz)",
            f"variable cf atom (v_vm>{cap})*{cap}/(v_vm+(v_vm<={cap}))+(v_vm<={cap})",
            "variable vxn atom vx*v_cf",
            "variable vyn atom vy*v_cf",
            "variable vzn atom vz*v_cf",
        ]

    def fill(self) -> None:
        t = self.t
        self.begin("fill")
        self.add(*self.setup_run(fill_wall=True))
        self.start_stage("fill")
        after: tuple[str, ...] = ()
        if t.pour_speed is not None:
            after = ("velocity all set v_vxn v_vyn v_vzn units box",)
        self.loop(
            "fill",
            f"((v_n-v_t0)*{_num(self.dt)}>={_num(fall_time(t))})*(v_kin<={_num(settle_energy(t))})",
            after,
        )
        self.end("fill")

    def compression(self) -> None:
        t = self.t
        self.begin("pre_compression")
        if t.gravity_off_after_fill:
            self.add("unfix grav")
        self.add(
            "unfix sample",
            "unfix wallf",
            "uncompute ffsum",
            *self.sampler(fill_wall=False),
            f"variable zp equal c_zmax+{_num(PLACE_GAP * t.radius)}",
            "variable zplace equal ${zp}",
            f"fix topmesh all mesh/surface/stress file {PLATE} type 2 move 0.0 0.0 ${{zplace}}",
            f"fix walltop all {_wall_model(t)} mesh n_meshes 1 meshes topmesh",
            "variable zbase equal ${zplace}",
            "variable sbase equal ${n}",
            f"variable vplaten equal {_num(-t.platen_speed)}",
            "fix movetop all move/mesh mesh topmesh linear/variable v_zero v_zero v_vmesh",
            "variable ftop equal f_topmesh[3]",
            *self.setup_run(fill_wall=False),
        )
        self.start_stage("pre_compression")
        self.loop("pre_compression", f"v_stop>={_num(t.pre_stress)}")
        self.end("pre_compression")

        self.begin("consolidation")
        self.add("variable hcons equal ${gap}")
        self.start_stage("consolidation")
        self.loop("consolidation", f"v_stop>={_num(t.consolidation_stress)}")
        self.end("consolidation")

        if t.hold_time is not None:
            self.begin("hold")
            self.velocity(0.0)
            self.start_stage("hold")
            rest = f"*(v_kin<={_num(settle_energy(t))})"
            after: tuple[str, ...] = ()
            if t.hold_quiet is not None:
                # the step of the last sample above the energy (the stage's start at first)
                self.add("variable tq equal ${t0}")
                after = (
                    f'if "${{kin}} > {_num(settle_energy(t))}" then "variable tq equal ${{n}}"',
                )
                rest = f"*((v_n-v_tq)*{_num(self.dt)}>={_num(t.hold_quiet)})"
            self.loop("hold", f"((v_n-v_t0)*{_num(self.dt)}>={_num(t.hold_time)}){rest}", after)
            self.end("hold")

        self.begin("unloading")
        self.velocity(t.platen_speed)
        self.start_stage("unloading", "${hcons}")
        low = t.unloaded_stress * t.consolidation_stress
        self.loop("unloading", f"v_stop<={_num(low)}")
        self.end("unloading")
        self.velocity(0.0)

    def release(self) -> None:
        t = self.t
        if not t.unconfined:
            self.add("jump SELF finish")
            return
        lx, ly = t.cell[0], t.cell[1]
        lo = -(WIDE - 1) / 2
        hi = (WIDE + 1) / 2
        self.begin("release")
        self.add(
            "variable zkeep equal ${ztop}",
            "unfix movetop",
            "unfix walltop",
            "unfix topmesh",
            "change_box all boundary f f f",
            f"change_box all x final {_num(lo * lx)} {_num(hi * lx)} "
            f"y final {_num(lo * ly)} {_num(hi * ly)} boundary m m f",
            f"fix topmesh all mesh/surface/stress file {PLATE_WIDE} type 2 move 0.0 0.0 ${{zkeep}}",
            f"fix walltop all {_wall_model(t)} mesh n_meshes 1 meshes topmesh",
            "variable zbase equal ${zkeep}",
            "variable sbase equal ${n}",
            "variable vplaten equal 0.0",
            "fix movetop all move/mesh mesh topmesh linear/variable v_zero v_zero v_vmesh",
            *self.setup_run(fill_wall=False),
        )
        self.start_stage("release")
        t_min, t_max = release_times(t)
        dt = _num(self.dt)
        self.loop(
            "release",
            f"((v_n-v_t0)*{dt}>={_num(t_min)})*(v_kin<={_num(settle_energy(t))})"
            f"+((v_n-v_t0)*{dt}>={_num(t_max)})",
        )
        self.end("release")

    def unconfined(self) -> None:
        t = self.t
        if not t.unconfined:
            return
        self.begin("unconfined")
        self.velocity(-t.platen_speed)
        self.add(
            "# demscale's failure detector (engine.uniaxial.measures.FailureDetector) on the",
            "# strength curve (strength_from: the top platen's stress or the interior's)",
            "variable peak equal 0.0",
            "variable below equal 1e300",
        )
        self.add(
            f"variable isb equal (v_peak>0)*(v_sdet<{_num(1 - t.failure_drop)}*v_peak)",
            f"variable fdone equal (v_strain-v_below)>={_num(t.failure_strain)}",
        )
        detector = (
            'if "${sdet} > ${peak}" then "variable peak equal ${sdet}"',
            'if "${isb} == 0" then "variable below equal 1e300"',
            'if "${isb} == 1 && ${strain} < ${below}" then "variable below equal ${strain}"',
            f'if "${{fdone}} > 0" then "print \'# failed ${{n}}\' append {CURVES} screen no"',
        )
        self.start_stage("unconfined")
        self.add(*detector)
        done = f"(v_fdone>0)+(v_strain>={_num(t.max_unconfined_strain)})"
        self.add(
            f"variable done equal {done}",
            f"variable over equal (v_n-v_t0)>={self.max_steps}",
        )
        # the detector after each sample, then the criterion on that sample
        self.add(
            "label loop_unconfined",
            'if "${done} > 0" then "jump SELF end_unconfined"',
            'if "${over} > 0" then &',
            f"  \"print '# error unconfined ${{n}} ${{stop}} ${{gap}} ${{kin}}' append {CURVES} "
            'screen no" "jump SELF finish"',
            f"run {self.S} pre no post no",
        )
        self.row("unconfined")
        self.add(*detector, "jump SELF loop_unconfined", "label end_unconfined")
        self.velocity(0.0)
        self.end("unconfined")


def deck(test, skin: float | None = None, radii: np.ndarray | None = None) -> str:
    """The LIGGGHTS 3.8 input deck of ``test`` (an :class:`engine.UniaxialTest`; see the
    module docstring): ``skin`` the Verlet skin [m] (default :data:`SKIN_RADII` largest
    radii), ``radii`` those of the packing [m] (default: the test's poured cloud). Raises
    :class:`engine.ParameterError` for what it cannot express (:func:`check_exportable`)."""
    check_exportable(test)
    if radii is None:
        radii = test.initial_packing()[1]
    rmax = float(np.max(radii))
    if skin is None:
        skin = SKIN_RADII * rmax
    if not (math.isfinite(skin) and skin > 0):
        raise ParameterError("skin", skin, "a length > 0 m")
    return _Deck(test, skin, rmax).build()


def probe_deck(
    test,
    positions: np.ndarray,
    radii: np.ndarray,
    steps: int,
    every: int,
    periodic: bool = True,
    skin: float | None = None,
) -> dict[str, str]:
    """The files of a probe deck: ``test``'s materials, walls and measures on the packing
    ``positions``, ``radii`` [m] at rest, run ``steps`` steps with a sample line every
    ``every`` steps in ``probe.txt`` (:data:`COLUMNS`, then the sums over the particles of
    the total force and of the walls' forces on them [N]); ``periodic`` False walls the cell
    in x and y instead. What it is for: demscale's measures of one state against the deck's
    (tests), and whether LIGGGHTS' pair forces sum to zero (benchmarks/liggghts_deck.py)."""
    check_exportable(test)
    rmax = float(np.max(radii))
    d = _Deck(test, SKIN_RADII * rmax if skin is None else skin, rmax)
    d.probe_every = every
    return {
        "in.probe": d.probe(steps, every, periodic),
        DATA: data_file(test, positions, radii),
    }


def write_deck(test, directory, skin: float | None = None) -> Path:
    """Write the deck folder of ``test`` into ``directory`` (created): ``in.demscale``, the
    poured cloud ``packing.data``, the plates ``plate.stl`` and ``plate_wide.stl`` and the
    test as ``test.json``. Returns the deck's path. LIGGGHTS runs it there, unmodified:
    ``liggghts -in in.demscale`` (its output: ``curves.txt``, ``stage_<name>.dump``,
    ``log.liggghts``; :func:`engine.io.liggghts_read.read_output` reads them back)."""
    pos, radii = test.initial_packing()
    text = deck(test, skin, radii)
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    lx, ly = test.cell[0], test.cell[1]
    lo, hi = -(WIDE - 1) / 2, (WIDE + 1) / 2
    files = {
        DECK: text,
        DATA: data_file(test, pos, radii),
        PLATE: plate_stl(0.0, 0.0, lx, ly),
        PLATE_WIDE: plate_stl(lo * lx, lo * ly, hi * lx, hi * ly, "plate_wide"),
        TEST: json.dumps(test.to_dict(), indent=1) + "\n",
    }
    for name, body in files.items():
        (out / name).write_text(body)
    for stale in [out / CURVES, out / LOG, *out.glob(STAGE_DUMP.format("*"))]:
        stale.unlink(missing_ok=True)
    return out / DECK


__all__ = [
    "COLUMNS",
    "CURVES",
    "DATA",
    "DECK",
    "LOG",
    "STAGES",
    "STAGE_DUMP",
    "TEST",
    "check_exportable",
    "data_file",
    "deck",
    "differences",
    "plate_stl",
    "probe_deck",
    "write_deck",
]
