"""Stateless compiled contact-law kernels (scalar in, scalar out).

Units: overlaps and displacements [m], velocities [m/s], forces [N], stiffnesses [N/m],
moduli [Pa], masses [kg], torques [N m]. Sign conventions (PHYSICS.md): the overlap ``d > 0``
means the surfaces interpenetrate; ``n`` is the unit vector from particle j to particle i (from
the wall to the particle); a normal force is positive when repulsive; ``v`` is the velocity of
i's contact point relative to j's, so ``vn = v . n < 0`` while approaching.

Composition order, written once in :func:`bilinear_contact` and :func:`hertz_contact`
(LAMMPS granular order): elastic-plastic-adhesive normal force, then normal damping, then the
friction cap from the normal force, then the tangential spring, then (in the step kernel,
from the returned elastic force) rolling resistance.

The boolean arguments (``plastic``, ``adhesion``, ...) are compile-time constants at every call
site in the step kernel, so the branches a scene does not use are compiled out.
"""

from __future__ import annotations

import math

from numba import njit

from .config import NJIT, ROLLING_OMEGA_EPS


@njit(**NJIT)
def bilinear_normal_force(d, dmax, k1, k2, f0, kadh):
    r"""Hysteretic normal force of the bilinear adhesive elasto-plastic law.

    .. math::
        d_{max} \leftarrow \max(d_{max}, d),\quad d_p = (1 - K_1/K_2)\,d_{max},\quad
        f_{hys} = f_0 + \min\big(K_1 d,\ \max(K_2 (d - d_p),\ -k_{adh} d)\big)

    Args: overlap d [m] (> 0), largest overlap of this contact so far dmax [m], loading
    stiffness k1 [N/m], unloading/reloading stiffness k2 [N/m] (>= k1), adhesion f0 [N] (<= 0),
    adhesive branch slope kadh [N/m] (>= 0).
    Returns: (f_hys [N], updated dmax [m]). Reference: Thakur et al. 2014, Granular Matter 16:383.
    """
    if d > dmax:
        dmax = d
    dp = (1.0 - k1 / k2) * dmax
    f = f0 + min(k1 * d, max(k2 * (d - dp), -kadh * d))
    return f, dmax


@njit(**NJIT)
def bilinear_friction_limit(mu_s, f_hys, f0, kadh, d):
    r"""Adhesion-aware Coulomb limit :math:`\mu_s |f_{hys} - f_0 + k_{adh} d|` [N].

    Zero on the adhesive plateau (f_hys = f0, kadh = 0): a contact held only by adhesion
    carries no friction (Thakur et al. 2014).
    """
    return mu_s * abs(f_hys - f0 + kadh * d)


@njit(**NJIT)
def viscous_damping_coefficient(zeta, m_eff, k):
    r"""Viscous damping coefficient :math:`c = 2\zeta\sqrt{m_{eff} k}` [N s/m] for a linear
    spring k [N/m], effective mass m_eff [kg] and damping ratio zeta [-]."""
    return 2.0 * zeta * math.sqrt(m_eff * k)


@njit(**NJIT)
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


@njit(**NJIT)
def rolling_torque(wx, wy, wz, mu_r, fn_abs, radius):
    r"""Constant directional rolling-resistance torque (EDEM "standard") [N m].

    .. math:: \tau = -\mu_r\,|F_n|\,R\,\omega/|\omega|

    Args: angular velocity of the particle w [rad/s], rolling friction mu_r [-], magnitude of
    the contact's elastic normal force fn_abs [N], particle radius [m]. Zero when
    |w| <= ``ROLLING_OMEGA_EPS``.
    """
    w2 = wx * wx + wy * wy + wz * wz
    if w2 <= ROLLING_OMEGA_EPS * ROLLING_OMEGA_EPS:
        return 0.0, 0.0, 0.0
    s = -mu_r * fn_abs * radius / math.sqrt(w2)
    return s * wx, s * wy, s * wz


@njit(**NJIT)
def hertz_normal_force(d, e_star, r_star):
    r"""Hertz elastic normal force and normal contact stiffness.

    .. math:: F_n = \tfrac43 E^*\sqrt{R^*}\,d^{3/2}, \qquad S_n = 2E^*\sqrt{R^* d}

    Args: overlap d [m] (> 0), effective modulus e_star [Pa], effective radius r_star [m].
    Returns: (F_n [N], S_n [N/m]). Reference: Johnson, Contact Mechanics (1985).
    """
    a = math.sqrt(r_star * d)
    return (4.0 / 3.0) * e_star * a * d, 2.0 * e_star * a


@njit(**NJIT)
def hertz_tangential_stiffness(d, g_star, r_star):
    r"""Mindlin no-slip tangential stiffness :math:`S_t = 8G^*\sqrt{R^* d}` [N/m]."""
    return 8.0 * g_star * math.sqrt(r_star * d)


@njit(**NJIT)
def bilinear_contact(
    d,
    nx,
    ny,
    nz,
    vx,
    vy,
    vz,
    dmax,
    xix,
    xiy,
    xiz,
    m_eff,
    k1,
    k2,
    f0,
    kadh,
    kt,
    zeta,
    mu_s,
    dt,
    plastic,
    adhesion,
    friction,
    damping,
):
    r"""One contact of the bilinear adhesive elasto-plastic law, composed in the fixed order.

    Args: overlap d [m] (> 0), unit normal n (j -> i), relative contact velocity v [m/s],
    history (dmax [m], tangential spring xi [m]), effective mass m_eff [kg], law parameters
    (k1, k2, kadh, kt [N/m], f0 [N], zeta, mu_s [-]), dt [s]; feature switches.
    Returns: (F_n [N] normal force with damping, f_hys [N] (for the rolling torque),
    F_t (3) [N], dmax [m], xi (3) [m]). The force acts on i; j receives the opposite.
    """
    f0_ = f0 if adhesion else 0.0
    if plastic:
        f_hys, dmax = bilinear_normal_force(d, dmax, k1, k2, f0_, kadh)
    else:
        if d > dmax:
            dmax = d
        f_hys = f0_ + k1 * d  # k2 == k1: no plastic overlap, the law is linear elastic
    vn = vx * nx + vy * ny + vz * nz
    fn = f_hys
    sm = 0.0
    if damping:
        sm = math.sqrt(m_eff)
        fn -= 2.0 * zeta * sm * math.sqrt(k1) * vn
    ftx = 0.0
    fty = 0.0
    ftz = 0.0
    if friction:
        vtx = vx - vn * nx
        vty = vy - vn * ny
        vtz = vz - vn * nz
        cap = bilinear_friction_limit(mu_s, f_hys, f0_, kadh, d)
        ct = 2.0 * zeta * sm * math.sqrt(kt) if damping else 0.0
        ftx, fty, ftz, xix, xiy, xiz = tangential_spring_force(
            xix, xiy, xiz, nx, ny, nz, vtx, vty, vtz, kt, ct, cap, dt
        )
    return fn, f_hys, ftx, fty, ftz, dmax, xix, xiy, xiz


@njit(**NJIT)
def hertz_contact(
    d,
    nx,
    ny,
    nz,
    vx,
    vy,
    vz,
    xix,
    xiy,
    xiz,
    r_star,
    m_star,
    e_star,
    g_star,
    damp_factor,
    mu,
    dt,
    friction,
    damping,
):
    r"""One Hertz-Mindlin (no slip) contact, composed in the fixed order.

    Normal: :math:`F_n = \tfrac43E^*\sqrt{R^*}d^{3/2} - c_n v_n`,
    :math:`c_n = \text{damp\_factor}\sqrt{S_n m^*}`; tangential: spring
    :math:`S_t = 8G^*\sqrt{R^*d}` on the accumulated displacement with
    :math:`c_t = \text{damp\_factor}\sqrt{S_t m^*}`, capped at :math:`\mu F_n^{el}`.

    Args: overlap d [m], unit normal n, relative contact velocity v [m/s], spring xi [m],
    effective radius r_star [m] and mass m_star [kg] (for a wall: the particle's), moduli
    e_star, g_star [Pa], damp_factor = -2 sqrt(5/6) beta [-], friction mu [-], dt [s].
    Returns: (F_n [N], F_n elastic [N], F_t (3) [N], xi (3) [m]).
    """
    f_el, s_n = hertz_normal_force(d, e_star, r_star)
    vn = vx * nx + vy * ny + vz * nz
    fn = f_el
    if damping:
        fn -= damp_factor * math.sqrt(s_n * m_star) * vn
    ftx = 0.0
    fty = 0.0
    ftz = 0.0
    if friction:
        vtx = vx - vn * nx
        vty = vy - vn * ny
        vtz = vz - vn * nz
        s_t = hertz_tangential_stiffness(d, g_star, r_star)
        ct = damp_factor * math.sqrt(s_t * m_star) if damping else 0.0
        ftx, fty, ftz, xix, xiy, xiz = tangential_spring_force(
            xix, xiy, xiz, nx, ny, nz, vtx, vty, vtz, s_t, ct, mu * f_el, dt
        )
    return fn, f_el, ftx, fty, ftz, xix, xiy, xiz
