"""The one contact composition, and the scalar kernels every law shares.

Units: overlaps and displacements [m], velocities [m/s], forces [N], stiffnesses [N/m],
masses [kg], torques [N m]. Sign conventions (PHYSICS.md): the overlap ``d > 0`` means the
surfaces interpenetrate; ``n`` is the unit vector from particle j to particle i (from the wall
to the particle); a normal force is positive when repulsive.

:func:`composition` makes, for a law family (:class:`engine.contact.kernel.LawKernel`), the
contact the step kernel calls for every particle-particle AND every particle-wall contact
(LAMMPS GRANULAR ``GranularModel`` style: one force calculation serves both). Its fixed
order:

1. contact-point velocity (:func:`contact_velocity`);
2. normal force with the law's adhesion and plasticity: the family's ``normal_force``;
3. normal damping (:func:`viscous_damping_coefficient` on the contact's normal stiffness);
4. the friction cap: ``mu_s |f_cap|`` with the law's cap force, or ``mu_s |F_n|`` with the
   ``normal_cap`` switch;
5. the tangential spring with the family's ``tangential_stiffness``, turned into the current
   tangent plane, damped and capped (:func:`tangential_spring_force`);
6. the torque split (both bodies turn the same way: ``t_i = -R_i n x F_t``,
   ``t_j = -R_j n x F_t``) and the rolling-resistance moment ``mu_r |f_el|``, applied per
   particle by :func:`rolling_torque`;
7. history write-back (largest overlap or contact marker, tangential spring).

The switch tuple ``flags`` holds compile-time constants at every call site in the step
kernel, so the branches a scene does not use are compiled out. A switched-on feature with its
neutral parameter (``mu = 0``, ``mu_r = 0``, ``zeta = 0``, a law's own neutral values) gives
bit-identical results to the feature switched off (tests/engine/test_kernels.py).
"""

from __future__ import annotations

import functools
import math
from collections import namedtuple

from numba import njit

from ..core.config import NJIT_INLINE, ROLLING_OMEGA_EPS

#: What :func:`composition` makes for a law family: ``force`` (:func:`contact_force`'s
#: signature) and ``contact`` (the step kernel's call, with the history row).
Composition = namedtuple("Composition", "force contact")


@njit(**NJIT_INLINE)
def viscous_damping_coefficient(zeta, m_eff, k):
    r"""Viscous damping coefficient :math:`c = 2\zeta\sqrt{m_{eff} k}` [N s/m] for a spring of
    stiffness k [N/m], effective mass m_eff [kg] and damping ratio zeta [-]."""
    return 2.0 * zeta * math.sqrt(m_eff * k)


@njit(**NJIT_INLINE)
def contact_velocity(vx, vy, vz, sx, sy, sz, nx, ny, nz):
    r"""Normal and tangential relative velocity of the contact point [m/s].

    .. math:: v_n = (v_i - v_j)\cdot n, \qquad
              v_t = (v_i - v_j) - v_n n - (R_i\omega_i + R_j\omega_j)\times n

    Args: translational relative velocity v = v_i - v_j [m/s], spin sum
    s = R_i w_i + R_j w_j [m/s] (a wall: R_i w_i), unit normal n (j -> i).
    ``v_n`` uses the translation only: the spin term is perpendicular to n, so the normal
    velocity (and the damping) does not depend on whether rotation is compiled in.
    Returns: (vn, vtx, vty, vtz).
    """
    vn = vx * nx + vy * ny + vz * nz
    vtx = vx - vn * nx - (sy * nz - sz * ny)
    vty = vy - vn * ny - (sz * nx - sx * nz)
    vtz = vz - vn * nz - (sx * ny - sy * nx)
    return vn, vtx, vty, vtz


@njit(**NJIT_INLINE)
def tangential_spring_force(xix, xiy, xiz, nx, ny, nz, vtx, vty, vtz, kt, ct, cap, dt):
    r"""Incremental linear tangential spring with damping and a Coulomb cap.

    The stored spring :math:`\xi` [m] is first turned into the current tangent plane (normal
    component removed, length kept), then
    :math:`\xi \leftarrow \xi + v_t\,\Delta t`, :math:`F_t = -k_t\xi - c_t v_t`. If
    :math:`|F_t| > F_{cap}` the force is scaled to the cap and the spring truncated to match:
    :math:`\xi = -(F_t + c_t v_t)/k_t` (LAMMPS / MercuryDPM convention).

    Args: spring xi [m], unit normal n, tangential relative velocity vt [m/s], stiffness kt
    [N/m], damping ct [N s/m], cap [N] (>= 0), time step dt [s].
    Returns: (ftx, fty, ftz [N], xix, xiy, xiz [m]).
    """
    xn = xix * nx + xiy * ny + xiz * nz
    if xn != 0.0:
        old2 = xix * xix + xiy * xiy + xiz * xiz
        xix -= xn * nx
        xiy -= xn * ny
        xiz -= xn * nz
        new2 = xix * xix + xiy * xiy + xiz * xiz
        if new2 > 0.0:
            s = math.sqrt(old2 / new2)
            xix *= s
            xiy *= s
            xiz *= s
    xix += vtx * dt
    xiy += vty * dt
    xiz += vtz * dt
    ftx = -kt * xix - ct * vtx
    fty = -kt * xiy - ct * vty
    ftz = -kt * xiz - ct * vtz
    f2 = ftx * ftx + fty * fty + ftz * ftz
    if f2 > cap * cap:
        s = cap / math.sqrt(f2)
        ftx *= s
        fty *= s
        ftz *= s
        if kt > 0.0:
            xix = -(ftx + ct * vtx) / kt
            xiy = -(fty + ct * vty) / kt
            xiz = -(ftz + ct * vtz) / kt
    return ftx, fty, ftz, xix, xiy, xiz


@njit(**NJIT_INLINE)
def rolling_torque(wx, wy, wz, mu_r, fn_abs, radius):
    r"""Constant directional rolling-resistance torque (EDEM "standard") [N m].

    .. math:: \tau = -\mu_r\,|F_n|\,R\,\omega/|\omega|

    Args: angular velocity of the particle w [rad/s], rolling friction mu_r [-], magnitude of
    the contact's elastic normal force fn_abs [N], particle radius [m]. Zero when
    |w| <= ``ROLLING_OMEGA_EPS``. Every contact of a particle pulls against the same unit
    spin vector, so the step kernel calls it once per particle with ``mu_r = 1`` and
    ``fn_abs`` the particle's summed rolling moments ``sum mu_r |f_el|`` [N].
    """
    w2 = wx * wx + wy * wy + wz * wz
    if w2 <= ROLLING_OMEGA_EPS * ROLLING_OMEGA_EPS:
        return 0.0, 0.0, 0.0
    s = -mu_r * fn_abs * radius / math.sqrt(w2)
    return s * wx, s * wy, s * wz


@functools.cache  # once per family (a LawKernel hashes by identity)
def composition(kernel) -> Composition:
    """The contact composition of the law family ``kernel``
    (:class:`engine.contact.kernel.LawKernel`), made once per family: its ``normal_force`` and
    ``tangential_stiffness`` are bound in, everything else is shared by every law.

    ``force(d, nx, ny, nz, vx, vy, vz, sx, sy, sz, dmax, xix, xiy, xiz, r_star, m_eff, law,
    flags, dt)``: one contact, steps 1 to 5 of the module docstring. Args: overlap d [m]
    (> 0), unit normal n (j -> i), relative velocity v = v_i - v_j [m/s], spin sum
    s = R_i w_i + R_j w_j [m/s], history (dmax [m]: largest overlap or contact marker; spring
    xi [m]), effective radius r_star [m] and mass m_eff [kg] (a wall: the particle's), the
    family's parameter tuple ``law`` and switch tuple ``flags``, time step dt [s]. Returns
    (F_n [N] with damping, f_el [N], F_t (3) [N], dmax [m], xi (3) [m]); the force
    F_n n + F_t acts on i, j receives the opposite.

    ``contact(hist, k, d, nx, ny, nz, vx, vy, vz, sx, sy, sz, ri, rj, r_star, m_eff, law,
    flags, dt)``: ``force`` on the history row ``hist[k]`` (slot 0: dmax; slots 1-3: the
    tangential spring, with friction), written back in place, and the torque split; ri, rj
    are the radii [m] of the two bodies (a wall: rj = 0). Returns (force on i (3) [N], torque
    on i (3) [N m], torque on j (3) [N m], rolling moment ``mu_r |f_el|`` [N], 0 without
    rolling).
    """
    normal_force = kernel.normal_force
    tangential_stiffness = kernel.tangential_stiffness

    @njit(**NJIT_INLINE)
    def force(
        d, nx, ny, nz, vx, vy, vz, sx, sy, sz, dmax, xix, xiy, xiz, r_star, m_eff, law, flags, dt
    ):
        # 1. contact-point velocity
        vn, vtx, vty, vtz = contact_velocity(vx, vy, vz, sx, sy, sz, nx, ny, nz)
        # 2. normal force: the law's own (elastic, plastic, adhesive)
        f_el, stiff, f_cap, tangent, dmax = normal_force(d, dmax, r_star, law, flags)
        # 3. damping
        fn = f_el
        if flags.damping:
            fn -= viscous_damping_coefficient(law.zeta, m_eff, stiff) * vn
        ftx = 0.0
        fty = 0.0
        ftz = 0.0
        if flags.friction:
            # 4. friction cap
            if flags.normal_cap:
                cap = law.mu_s * abs(fn)
            else:
                cap = law.mu_s * abs(f_cap)
            # 5. tangential spring
            kt = tangential_stiffness(d, r_star, law, tangent)
            ct = viscous_damping_coefficient(law.zeta, m_eff, kt) if flags.damping else 0.0
            ftx, fty, ftz, xix, xiy, xiz = tangential_spring_force(
                xix, xiy, xiz, nx, ny, nz, vtx, vty, vtz, kt, ct, cap, dt
            )
        return fn, f_el, ftx, fty, ftz, dmax, xix, xiy, xiz

    @njit(**NJIT_INLINE)
    def contact(
        hist, k, d, nx, ny, nz, vx, vy, vz, sx, sy, sz, ri, rj, r_star, m_eff, law, flags, dt
    ):
        xix = 0.0
        xiy = 0.0
        xiz = 0.0
        if flags.friction:
            xix = hist[k, 1]
            xiy = hist[k, 2]
            xiz = hist[k, 3]
        fn, f_el, ftx, fty, ftz, dmax, xix, xiy, xiz = force(
            d,
            nx,
            ny,
            nz,
            vx,
            vy,
            vz,
            sx,
            sy,
            sz,
            hist[k, 0],
            xix,
            xiy,
            xiz,
            r_star,
            m_eff,
            law,
            flags,
            dt,
        )
        # 7. history write-back
        hist[k, 0] = dmax
        cx = 0.0
        cy = 0.0
        cz = 0.0
        if flags.friction:
            hist[k, 1] = xix
            hist[k, 2] = xiy
            hist[k, 3] = xiz
            # 6. torque split
            cx = ny * ftz - nz * fty
            cy = nz * ftx - nx * ftz
            cz = nx * fty - ny * ftx
        roll = law.mu_r * abs(f_el) if flags.rolling else 0.0
        return (
            fn * nx + ftx,
            fn * ny + fty,
            fn * nz + ftz,
            -ri * cx,
            -ri * cy,
            -ri * cz,
            -rj * cx,
            -rj * cy,
            -rj * cz,
            roll,
        )

    return Composition(force, contact)
