"""The ring shear cell in LIGGGHTS 3.8: geometry, the stresses from the lid's force and
torque, the packing, and the two decks (fill, consolidation and pre-shear; one shear point
from the pre-sheared restart). docs/SHEAR.md, "Against a ring shear cell (LIGGGHTS)".

The cell: an annular trough between two frictionless vertical cylinder walls (radii Ri, Ro
[m], about the z axis), a flat floor at z = 0. The bed is filled, settled under gravity,
gravity switched off and consolidated by a flat plate (servo) to sigma_pre; the grains whose
centres lie within one diameter of the floor and of the plate are then glued (demscale's
``platen_layer``): the base's grains turn about the axis as one body (``fix move rotate``:
Schulze's tester turns its trough), the lid's grains do not turn and move along z only, at
the servo's speed (``fix move variable``). Stresses on the lid (uniform over it):

    sigma = F_z / (pi (Ro^2 - Ri^2)),
    tau = T / (2 pi int_Ri^Ro r^2 dr) = 3 T / (2 pi (Ro^3 - Ri^3))

F_z [N] the axial force and T [N m] the axial torque of the bed on the lid's grains.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from engine.io.liggghts import to_liggghts
from engine.io.liggghts_deck import plate_stl

#: atom types: 1 particles, 2 the cylinder walls (frictionless), 3 floor and consolidation plate
PARTICLE, CYLINDER, PLATE = 1, 2, 3
#: the columns of every curve file (one row per curve sample: the sample's means)
COLUMNS = ("step", "torque_lid", "force_lid", "torque_base", "force_base", "z_lid", "z_base", "ke")


def annulus_area(ri: float, ro: float) -> float:
    """The lid's area pi (Ro^2 - Ri^2) [m^2] of an annulus of radii ``ri`` < ``ro`` [m]."""
    return math.pi * (ro * ro - ri * ri)


def torque_lever(ri: float, ro: float) -> float:
    """2 pi int_Ri^Ro r^2 dr = 2 pi (Ro^3 - Ri^3) / 3 [m^3]: the torque [N m] of a uniform
    shear stress of 1 Pa on the annulus' face about its axis."""
    return 2.0 * math.pi * (ro**3 - ri**3) / 3.0


def shear_stress(torque: float | np.ndarray, ri: float, ro: float):
    """The uniform shear stress [Pa] that exerts ``torque`` [N m] on the annulus ``ri``,
    ``ro`` [m]: T / (2 pi int_Ri^Ro r^2 dr)."""
    return torque / torque_lever(ri, ro)


def normal_stress(force: float | np.ndarray, ri: float, ro: float):
    """The normal stress [Pa] of an axial ``force`` [N] on the annulus ``ri``, ``ro`` [m]."""
    return force / annulus_area(ri, ro)


@dataclass(frozen=True)
class Ring:
    """A ring shear cell and its procedure. Lengths [m], stresses [Pa], times [s].

    ``width`` and ``height`` are the annulus' radial width and the bed's fill height at
    ``solid_fraction`` (as demscale's cell: particles = solid_fraction x volume / sphere
    volume); ``mean_radius`` (Ri + Ro) / 2. ``dt``, ``servo_gain`` [m / (Pa s)] and
    ``servo_time`` [s] are demscale's for the same test (its resolved step, its servo's
    proportional gain and relaxation time: the points' servo is PI with T_i = 5
    ``servo_time``; the pre-shear's is proportional only, as it was run);
    ``law`` the pair law (an ``engine.EEPA``/``BilinearAdhesive`` exportable by
    ``engine.io.liggghts.to_liggghts``); the wall law's Hertz constants are demscale's
    default shear test's (E, nu of the particle side and the wall material)."""

    law: object
    radius: float
    density: float
    mean_radius: float
    width: float
    height: float
    dt: float
    servo_gain: float
    servo_time: float | None = None
    preshear_stress: float = 10e3
    normal_stresses: tuple = (2e3, 4e3, 8e3)
    inertial_number: float = 1e-3
    max_speed: float = 0.05
    solid_fraction: float = 0.6
    lattice_fraction: float = 0.45
    output_interval: float = 1e-3
    settle_time: float = 0.25
    consolidation_time: float = 0.3
    preshear_strain: float = 0.8
    normal_time: float = 0.05
    failure_strain: float = 0.2
    failure_drop: float = 0.07
    chunk_strain: float = 0.005
    wall_E: float = 1e8
    wall_nu: float = 0.25
    wall_material_E: float = 2e11
    wall_material_nu: float = 0.3
    wall_restitution: float = 0.4
    plate_mu: float = 0.3
    seed: int = 1

    @property
    def ri(self) -> float:
        return self.mean_radius - self.width / 2

    @property
    def ro(self) -> float:
        return self.mean_radius + self.width / 2

    @property
    def area(self) -> float:
        return annulus_area(self.ri, self.ro)

    @property
    def lever(self) -> float:
        return torque_lever(self.ri, self.ro)

    @property
    def particles(self) -> int:
        v = 4.0 / 3.0 * math.pi * self.radius**3
        return round(self.solid_fraction * self.area * self.height / v)

    @property
    def sample_steps(self) -> int:
        return max(1, round(self.output_interval / self.dt))

    def speed(self, sigma: float, gap: float) -> float:
        """demscale's shear speed [m/s] at the mean radius: I (h / d) sqrt(sigma / rho), at
        most ``max_speed``."""
        d = 2 * self.radius
        return min(self.max_speed, self.inertial_number * gap / d * math.sqrt(sigma / self.density))

    # ------------------------------------------------------------------ packing
    def positions(self) -> np.ndarray:
        """A jittered cubic lattice of ``particles`` centres inside the annulus [m], at
        ``lattice_fraction``, the lowest layer one radius and a half above the floor."""
        d = 2 * self.radius
        a = d * (math.pi / 6 / self.lattice_fraction) ** (1 / 3)
        rng = np.random.default_rng(self.seed)
        n = math.ceil(self.ro / a)
        g = np.arange(-n, n + 1) * a
        x, y = np.meshgrid(g, g, indexing="ij")
        r = np.hypot(x, y)
        keep = (r > self.ri + 0.6 * d) & (r < self.ro - 0.6 * d)
        layer = np.column_stack([x[keep], y[keep]])
        layers = math.ceil(self.particles / len(layer))
        pts = np.concatenate(
            [
                np.column_stack([layer, np.full(len(layer), 1.5 * self.radius + k * a)])
                for k in range(layers)
            ]
        )[: self.particles]
        jitter = (a - d) / 2 * 0.9
        return pts + rng.uniform(-jitter, jitter, pts.shape)

    def data_file(self) -> str:
        """The packing as a LAMMPS ``atom_style granular`` data file, three atom types."""
        p = self.positions()
        top = float(p[:, 2].max()) + 4 * self.radius
        lo = -(self.ro + 2 * self.radius)
        lines = [
            "LAMMPS data file: ring shear cell (benchmarks/annular_shear)",
            "",
            f"{len(p)} atoms",
            "3 atom types",
            "",
            f"{lo!r} {-lo!r} xlo xhi",
            f"{lo!r} {-lo!r} ylo yhi",
            f"{-2 * self.radius!r} {top!r} zlo zhi",
            "",
            "Atoms",
            "",
        ]
        d, rho = 2 * self.radius, self.density
        lines += [
            f"{i + 1} 1 {d!r} {rho!r} {float(x)!r} {float(y)!r} {float(z)!r}"
            for i, (x, y, z) in enumerate(p)
        ]
        return "\n".join(lines) + "\n"

    def plate(self) -> str:
        """The consolidation plate: a square covering the annulus, at z = 0 (moved up)."""
        s = self.ro + self.radius
        return plate_stl(-s, -s, s, s, name="plate")

    # ------------------------------------------------------------------ deck parts
    def materials(self) -> list[str]:
        """``engine.io.liggghts.to_liggghts``'s fragment of the pair law (one atom type),
        widened to three types: every particle-particle value as the law's, the walls'
        restitution the wall law's, friction 0 on the cylinders and ``plate_mu`` on floor
        and plate, no rolling friction on walls; plus the walls' Hertz E and nu."""
        wall = {
            "coefficientRestitution": (self.wall_restitution, self.wall_restitution),
            "coefficientFriction": (0.0, self.plate_mu),
            "coefficientRollingFriction": (0.0, 0.0),
        }
        out = [
            f"fix m1 all property/global youngsModulus peratomtype {self.wall_E!r} "
            f"{self.wall_material_E!r} {self.wall_material_E!r}",
            f"fix m2 all property/global poissonsRatio peratomtype {self.wall_nu!r} "
            f"{self.wall_material_nu!r} {self.wall_material_nu!r}",
        ]
        pat = re.compile(r"^(fix \S+ all property/global (\w+)) peratomtypepair 1 (\S+)$")
        for line in to_liggghts(self.law, radius=self.radius).splitlines():
            m = pat.match(line)
            if not m:
                out.append(line)
                continue
            head, name, v = m.groups()
            cyl, plate = (float(v), float(v)) if name not in wall else wall[name]
            # wall-wall pairs never touch: the particle value (LIGGGHTS checks every entry)
            vals = [float(v), cyl, plate, cyl, float(v), float(v), plate, float(v), float(v)]
            out.append(f"{head} peratomtypepair 3 " + " ".join(repr(x) for x in vals))
        return out

    def _walls(self, group: str) -> list[str]:
        w = "wall/gran model hertz tangential history"
        return [
            f"fix floor {group} {w} primitive type {PLATE} zplane 0.0",
            f"fix inner {group} {w} primitive type {CYLINDER} zcylinder {self.ri!r} 0.0 0.0",
            f"fix outer {group} {w} primitive type {CYLINDER} zcylinder {self.ro!r} 0.0 0.0",
        ]

    def _header(self) -> list[str]:
        law = type(self.law).__name__
        return [
            "# ring shear cell (benchmarks/annular_shear/ring.py), LIGGGHTS 3.8, SI units",
            f"# Ri = {self.ri!r} m, Ro = {self.ro!r} m, fill height {self.height!r} m, "
            f"{self.particles} spheres of R = {self.radius!r} m, law {law}",
            f"# sigma = F_z / {self.area!r} m^2; tau = T / {self.lever!r} m^3 "
            "(2 pi (Ro^3 - Ri^3) / 3)",
        ]

    def _common(self) -> list[str]:
        return [
            f"neighbor {self.radius / 2!r} bin",
            "neigh_modify delay 0",
            *self.materials(),
            f"timestep {self.dt!r}",
        ]

    def _probes(self, constants: bool = True) -> list[str]:
        """Variables and computes of the curve columns (lid/base: torque about z [N m],
        axial force [N], mean centre height [m]; kinetic energy of the free grains [J]);
        with ``constants`` the servo's constants too."""
        out = [
            "variable tqa atom x*fy-y*fx",
            "compute tql lid reduce sum v_tqa",
            "compute tqb base reduce sum v_tqa",
            "compute kef free ke",
            "variable fzl equal fcm(lid,z)",
            "variable fzb equal fcm(base,z)",
            "variable zl equal xcm(lid,z)",
            "variable zb equal xcm(base,z)",
        ]
        return out + (self._constants() if constants else [])

    def _constants(self) -> list[str]:
        return [
            "variable zero equal 0.0",
            f"variable area equal {self.area!r}",
            f"variable gain equal {self.servo_gain!r}",
            f"variable vcap equal {self.max_speed!r}",
        ]

    def _servo(self, name: str, target: float, integral: str | None = None) -> list[str]:
        """The lid's vertical speed [m/s], a new variable ``name`` per stage (a variable a
        fix reads is never redefined): g (e + (1 / T_i) int e dt) clipped to +-vcap, e =
        F_z / A - target [Pa], demscale's PI servo with T_i = 5 ``servo_time``, the
        integral taken only while |e| < 10 % of the target (from the stage's start: the
        running mean of that e, fix ``integral``, times the stage's time; the stage starts
        at step 0). Without ``integral`` (or ``servo_time``) proportional only."""
        if not (integral and self.servo_time):
            e = f"(v_gain*(v_fzl/v_area-{target!r}))"
            return [
                f"variable {name} equal {e}+({e}<-v_vcap)*(-v_vcap-{e})+({e}>v_vcap)*(v_vcap-{e})",
            ]
        ti = 5.0 * self.servo_time
        out = [
            f"variable e_{name} equal v_fzl/v_area-{target!r}",
            f"variable ein_{name} equal v_e_{name}*(abs(v_e_{name})<{0.1 * target!r})",
            f"fix {integral} all ave/time 1 1 1 v_ein_{name} ave running",
        ]
        e = f"(v_gain*(v_e_{name}+f_{integral}*step*{self.dt!r}/{ti!r}))"
        clip = f"{e}+({e}<-v_vcap)*(-v_vcap-{e})+({e}>v_vcap)*(v_vcap-{e})"
        return [*out, f"variable {name} equal {clip}"]

    def _out(self, path: str) -> str:
        s = self.sample_steps
        return f"fix out all ave/time 1 {s} {s} c_tql v_fzl c_tqb v_fzb v_zl v_zb c_kef file {path}"

    def _rotate(self, fid: str, sign: int, speed_var: str) -> list[str]:
        """The base turning about +z (``sign`` 1) or -z at the mean radius' ``speed_var``."""
        return [
            f"variable period_{fid} equal 2*PI*{self.mean_radius!r}/${{{speed_var}}}",
            f"fix {fid} base move rotate 0.0 0.0 0.0 0.0 0.0 {sign} ${{period_{fid}}}",
        ]

    def preshear_deck(self) -> str:
        """Fill (gravity, ``settle_time``), consolidation (the plate under the servo at
        sigma_pre, ``consolidation_time``), gluing, pre-shear to ``preshear_strain`` at the
        mean radius; writes ``cons.txt``, ``preshear.txt``, ``meta.txt`` and
        ``preshear.restart``."""
        s, R, d = self.sample_steps, self.radius, 2 * self.radius
        nset = s * math.ceil(self.settle_time / self.dt / s)
        ncons = s * math.ceil(self.consolidation_time / self.dt / s)
        sig = self.preshear_stress
        return "\n".join(
            [
                *self._header(),
                "units si",
                "atom_style granular",
                "atom_modify map array",
                "boundary f f f",
                "newton off",
                "processors * * 1",
                "communicate single vel yes",
                "hard_particles yes",
                "read_data ring.data",
                *self._common(),
                *self._walls("all"),
                "fix grav all gravity 9.81 vector 0.0 0.0 -1.0",
                "fix integr all nve/sphere",
                "thermo_style custom step atoms ke cpu",
                f"thermo {10 * s}",
                "# fill: settle under gravity",
                f"run {nset}",
                "unfix grav",
                "# consolidation: the plate down under the servo to sigma_pre",
                f"variable ztop equal bound(all,zmax)+{1.2 * R!r}",
                f"fix plate all mesh/surface/stress file plate.stl type {PLATE} "
                "move 0.0 0.0 ${ztop}",
                "fix platew all wall/gran model hertz tangential history "
                "mesh n_meshes 1 meshes plate",
                *self._constants(),
                "variable sp equal f_plate[3]/v_area",
                f"variable ec equal (v_gain*(v_sp-{sig!r}))",
                "variable vzc equal v_ec+(v_ec<-v_vcap)*(-v_vcap-v_ec)+(v_ec>v_vcap)*(v_vcap-v_ec)",
                "fix moveplate all move/mesh mesh plate linear/variable v_zero v_zero v_vzc",
                f"fix cons all ave/time 1 {s} {s} v_sp file cons.txt",
                f"run {ncons}",
                "unfix cons",
                "# glue the platens: centres within one diameter of the floor and of the plate",
                f"variable zg equal bound(all,zmax)+{R!r}-{d!r}",
                "region rlid block INF INF INF INF ${zg} INF units box",
                f"region rbase block INF INF INF INF INF {d!r} units box",
                "group lid region rlid",
                "group base region rbase",
                "group glued union lid base",
                "group free subtract all glued",
                "unfix moveplate",
                "unfix platew",
                "unfix plate",
                "unfix integr",
                "unfix floor",
                "unfix inner",
                "unfix outer",
                *self._walls("free"),
                "fix integr free nve/sphere",
                "velocity glued set 0.0 0.0 0.0",
                "set group glued omegax 0.0 omegay 0.0 omegaz 0.0",
                *self._probes(constants=False),
                "variable h0 equal v_zl-v_zb",
                "variable h equal ${h0}",
                f"variable v0 equal {self.inertial_number!r}*v_h/{d!r}"
                f"*sqrt({sig!r}/{self.density!r})",
                "variable vpre equal v_v0+(v_v0>v_vcap)*(v_vcap-v_v0)",
                f"variable npre equal {s}*ceil({self.preshear_strain!r}*v_h/${{vpre}}"
                f"/{self.dt!r}/{s})",
                'print "gap ${h} speed ${vpre} steps ${npre}" append meta.txt screen no',
                'print "lid $(count(lid)) base $(count(base)) free $(count(free))" '
                "append meta.txt screen no",
                *self._servo("vzpre", sig),
                "reset_timestep 0",
                "fix servo lid move variable NULL NULL NULL v_zero v_zero v_vzpre",
                *self._rotate("rot", 1, "vpre"),
                self._out("preshear.txt"),
                "run ${npre}",
                "unfix out",
                "unfix rot",
                "unfix servo",
                "write_restart preshear.restart",
                'print "done" append meta.txt screen no',
                "",
            ]
        )

    def point_deck(self, k: int, gap: float) -> str:
        """Shear point ``k`` (``normal_stresses[k]``) from ``preshear.restart``: reverse at
        the pre-shear speed until the lid's torque (a sample's mean) is <= 0, the servo to
        sigma_n for ``normal_time``, then forward at the speed for sigma_n in chunks of
        ``chunk_strain`` until a chunk pair's mean falls ``failure_drop`` below its largest
        or ``failure_strain``. ``gap`` [m]: the pre-shear's gap (the strains' and speeds'
        h). Writes ``reverse_k.txt``, ``normal_k.txt``, ``shear_k.txt``."""
        s = self.sample_steps
        sn = self.normal_stresses[k]
        vpre = self.speed(self.preshear_stress, gap)
        vn = self.speed(sn, gap)
        nnorm = s * math.ceil(self.normal_time / self.dt / s)
        chunk = s * math.ceil(self.chunk_strain * gap / vn / self.dt / s)
        nmax = math.ceil(self.failure_strain / self.chunk_strain)
        nrev = math.ceil(0.1 * gap / vpre / self.dt / s)
        return "\n".join(
            [
                *self._header(),
                f"# point {k}: sigma_n = {sn!r} Pa; gap {gap!r} m; speeds {vpre!r}, {vn!r} m/s",
                "hard_particles yes",
                "read_restart preshear.restart",
                "newton off",
                "communicate single vel yes",
                *self._common(),
                *self._walls("free"),
                "fix integr free nve/sphere",
                *self._probes(),
                f"variable vpre equal {vpre!r}",
                f"variable vn equal {vn!r}",
                "# reverse until the lid's torque is <= 0 (run 0: the restart's data taken up",
                "# first; LIGGGHTS refuses reset_timestep after a restart otherwise)",
                "run 0",
                "reset_timestep 0",
                *self._servo("vzr", self.preshear_stress, "ir"),
                "fix servo lid move variable NULL NULL NULL v_zero v_zero v_vzr",
                *self._rotate("rev", -1, "vpre"),
                self._out(f"reverse_{k}.txt"),
                "# flags, not values, go into if: its Boolean parser reads no 1e-05 notation",
                "variable revd equal f_out[1]<=0.0",
                "variable nr loop " + str(nrev),
                "label rev",
                f"run {s}",
                'if "${revd} > 0" then "jump SELF rev_done"',
                "next nr",
                "jump SELF rev",
                "label rev_done",
                "unfix out",
                "unfix rev",
                "unfix servo",
                *(["unfix ir"] if self.servo_time else []),
                "velocity base set 0.0 0.0 0.0",
                "set group base omegax 0.0 omegay 0.0 omegaz 0.0",
                "# normal stage: the servo to sigma_n, the base at rest",
                "reset_timestep 0",
                *self._servo("vzn", sn, "inn"),
                "fix servo lid move variable NULL NULL NULL v_zero v_zero v_vzn",
                self._out(f"normal_{k}.txt"),
                f"run {nnorm}",
                "unfix out",
                "unfix servo",
                *(["unfix inn"] if self.servo_time else []),
                "# shear forward to failure",
                "reset_timestep 0",
                *self._servo("vzs", sn, "ish"),
                "fix servo lid move variable NULL NULL NULL v_zero v_zero v_vzs",
                *self._rotate("fwd", 1, "vn"),
                self._out(f"shear_{k}.txt"),
                f"fix chunk all ave/time 1 {chunk} {chunk} c_tql",
                "# chunk means in integer micro-N m (no exponent notation in substitutions)",
                "variable tc equal round(1e6*f_chunk)",
                "variable prev equal 0",
                "variable peak equal -1000000000",
                f"variable nc loop {nmax}",
                "label fwd",
                f"run {chunk}",
                "variable pair equal round(((${prev})+(${tc}))/2)",
                "variable peak equal (${peak})"
                "+(${nc}>1)*((${pair})>(${peak}))*((${pair})-(${peak}))",
                "variable stop equal (${nc}>3)"
                f"*((${{pair}})<{1 - self.failure_drop!r}*(${{peak}}))",
                'if "${stop} > 0" then "jump SELF fwd_done"',
                "variable prev equal ${tc}",
                "next nc",
                "jump SELF fwd",
                "label fwd_done",
                f'print "point {k} done" append meta.txt screen no',
                "",
            ]
        )
