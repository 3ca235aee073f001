"""Stateless compiled contact-law kernels and the one contact composition.

Units: overlaps and displacements [m], velocities [m/s], forces [N], stiffnesses [N/m],
moduli [Pa], masses [kg], torques [N m]. Sign conventions (PHYSICS.md): the overlap ``d > 0``
means the surfaces interpenetrate; ``n`` is the unit vector from particle j to particle i (from
the wall to the particle); a normal force is positive when repulsive.

:func:`contact` is the one composition, called by the step kernel for every particle-particle
AND every particle-wall contact (LAMMPS GRANULAR ``GranularModel`` style: one force calculation
serves both). Its fixed order:

1. contact-point velocity (:func:`contact_velocity`);
2. normal force with adhesion and plasticity (:func:`bilinear_normal_force`, or the
   non-linear :func:`eepa_normal_force`) or Hertz (:func:`hertz_normal_force`);
3. normal damping (:func:`viscous_damping_coefficient` on the contact's normal stiffness);
4. the friction cap from the normal force (:func:`friction_limit`, or ``mu_s |F_n|`` with
   the ``normal_cap`` switch);
5. the tangential spring, turned into the current tangent plane, damped and capped
   (:func:`tangential_spring_force`);
6. the torque split (both bodies turn the same way: ``t_i = -R_i n x F_t``,
   ``t_j = -R_j n x F_t``) and the rolling-resistance moment ``mu_r |f_el|``, applied per
   particle by :func:`rolling_torque`;
7. history write-back (largest overlap or contact marker, tangential spring).

The boolean arguments of :func:`contact` (``hertz``, ``plastic``, ...) are compile-time
constants at every call site in the step kernel, so the branches a scene does not use are
compiled out. A switched-on feature with its neutral parameter (``f0 = 0``, ``kadh = 0``,
``k2 = k1``, ``mu = 0``, ``mu_r = 0``, ``zeta = 0``) gives bit-identical results to the feature
switched off (tests/engine/test_kernels.py holds the kernels to this).
"""

from __future__ import annotations

import math
from collections import namedtuple

from numba import njit

from ..core.config import NJIT_INLINE, ROLLING_OMEGA_EPS

#: Parameters of one contact law as the kernel reads them (floats; a law that lacks one
#: passes its neutral value). ``k_n``: bilinear loading stiffness K1 [N/m], or Hertz E* [Pa];
#: ``k_unload``: bilinear K2 [N/m]; ``f0``: adhesion [N] (<= 0); ``kadh``: adhesive branch
#: slope [N/m]; ``k_t``: bilinear tangential stiffness Kt [N/m], or Hertz G* [Pa];
#: ``zeta``: damping ratio applied to the contact's stiffness [-] (Hertz: sqrt(5/6) zeta,
#: Tsuji et al. 1992); ``mu_s``: sliding friction [-]; ``mu_r``: rolling friction [-].
#: ``n``, ``chi``: EEPA overlap and adhesive exponents [-] (1 for the bilinear and Hertz laws).
ContactLaw = namedtuple(
    "ContactLaw", "k_n k_unload f0 kadh k_t zeta mu_s mu_r n chi", defaults=(1.0, 1.0)
)

#: Compile-time switches of :func:`contact`: Hertz instead of bilinear normal law, plastic
#: unloading branch, tangential spring and friction, normal and tangential damping, rolling,
#: the non-linear EEPA branches (exponents n, chi), the friction cap on the total normal force
#: (LIGGGHTS convention) instead of the adhesion-aware one.
LawFlags = namedtuple(
    "LawFlags", "hertz plastic friction damping rolling eepa normal_cap", defaults=(False, False)
)


@njit(**NJIT_INLINE)
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


@njit(**NJIT_INLINE)
def friction_limit(mu_s, f_el, f0, f_adh):
    r"""Adhesion-aware Coulomb limit :math:`\mu_s |f_{el} - f_0 + f_{adh}|` [N], with
    :math:`f_{adh} = k_{adh} d^\chi` the adhesive branch's pull at this overlap.

    Zero on the adhesive plateau (f_el = f0, kadh = 0): a contact held only by adhesion
    carries no friction (Thakur et al. 2014). Hertz (f0 = f_adh = 0): ``mu |F_n^el|``.
    Args: friction mu_s [-], elastic (hysteretic) normal force f_el [N], adhesion f0 [N],
    adhesive-branch term f_adh = kadh d^chi [N] (bilinear: kadh d).
    """
    return mu_s * abs(f_el - f0 + f_adh)


@njit(**NJIT_INLINE)
def eepa_normal_force(d, dmax, k1, k2, f0, kadh, n, chi):
    r"""Hysteretic normal force of the non-linear EEPA law (Morrissey 2013).

    .. math::
        d_{max} \leftarrow \max(d_{max}, d),\quad d_p^n = (1 - K_1/K_2)\,d_{max}^n,\quad
        f_{hys} = f_0 + \min\big(K_1 d^n,\ \max(K_2 (d^n - d_p^n),\ -k_{adh} d^\chi)\big)

    Args: overlap d [m] (> 0), largest overlap so far dmax [m], loading stiffness k1
    [N/m^n], unloading stiffness k2 [N/m^n] (>= k1), adhesion f0 [N] (<= 0), adhesive
    stiffness kadh [N/m^chi] (>= 0), exponents n, chi [-] (>= 1).
    Returns: (f_hys [N], tangent factor n d^(n-1) [m^(1-n)] (the loading tangent stiffness
    is K1 times it, the tangential stiffness kt times it), adhesive-branch pull kadh d^chi
    [N], updated dmax [m]). With n = chi = 1 every operation is that of
    :func:`bilinear_normal_force` (x**1.0 == x and x**0.0 == 1.0 exactly), so the force is the
    same to the last bit.
    """
    if d > dmax:
        dmax = d
    dn = d**n
    dpn = (1.0 - k1 / k2) * dmax**n
    f_adh = kadh * d**chi if kadh != 0.0 else 0.0  # no power where there is no branch
    f = f0 + min(k1 * dn, max(k2 * (dn - dpn), -f_adh))
    # n d^(n-1) as n d^n / d: one power less (d / d == 1 exactly, so n = 1 gives 1)
    return f, n * dn / d, f_adh, dmax


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


@njit(**NJIT_INLINE)
def hertz_normal_force(d, e_star, r_star):
    r"""Hertz elastic normal force and normal contact stiffness.

    .. math:: F_n = \tfrac43 E^*\sqrt{R^*}\,d^{3/2}, \qquad S_n = 2E^*\sqrt{R^* d}

    Args: overlap d [m] (> 0), effective modulus e_star [Pa], effective radius r_star [m].
    Returns: (F_n [N], S_n [N/m]). Reference: Johnson, Contact Mechanics (1985).
    """
    a = math.sqrt(r_star * d)
    return (4.0 / 3.0) * e_star * a * d, 2.0 * e_star * a


@njit(**NJIT_INLINE)
def hertz_tangential_stiffness(d, g_star, r_star):
    r"""Mindlin no-slip tangential stiffness :math:`S_t = 8G^*\sqrt{R^* d}` [N/m]."""
    return 8.0 * g_star * math.sqrt(r_star * d)


@njit(**NJIT_INLINE)
def contact_force(
    d, nx, ny, nz, vx, vy, vz, sx, sy, sz, dmax, xix, xiy, xiz, r_star, m_eff, law, flags, dt
):
    r"""One contact, composed in the fixed order (steps 1 to 5 of the module docstring).

    Normal force: bilinear :math:`f_{el} = f_{hys}` (:func:`bilinear_normal_force`, or
    :math:`f_0 + K_1 d` without plasticity) with stiffness :math:`K_1`, or Hertz
    :math:`f_{el} = \tfrac43 E^*\sqrt{R^*}d^{3/2}` with stiffness :math:`S_n`; damping
    :math:`F_n = f_{el} - c_n v_n`, :math:`c_n = 2\zeta\sqrt{m\,S}`; tangential stiffness
    :math:`K_t` or :math:`S_t = 8G^*\sqrt{R^* d}` with :math:`c_t = 2\zeta\sqrt{m\,K_t}`, capped
    at :math:`\mu_s|f_{el} - f_0 + k_{adh} d|`.

    Args: overlap d [m] (> 0), unit normal n (j -> i), relative velocity v = v_i - v_j [m/s],
    spin sum s = R_i w_i + R_j w_j [m/s], history (dmax [m]: largest overlap, or the current
    one for Hertz; spring xi [m]), effective radius r_star [m] and mass m_eff [kg] (a wall:
    the particle's), the law's parameters ``law`` (:data:`ContactLaw`), its switches ``flags``
    (:data:`LawFlags`), time step dt [s].
    Returns: (F_n [N] with damping, f_el [N], F_t (3) [N], dmax [m], xi (3) [m]). The force
    F_n n + F_t acts on i; j receives the opposite.
    """
    # 1. contact-point velocity
    vn, vtx, vty, vtz = contact_velocity(vx, vy, vz, sx, sy, sz, nx, ny, nz)
    # 2. normal force: elastic, plastic, adhesive
    if flags.hertz:
        f_el, stiff = hertz_normal_force(d, law.k_n, r_star)
        f_adh = 0.0
        dmax = d
    elif flags.eepa:
        f_el, tangent, f_adh, dmax = eepa_normal_force(
            d, dmax, law.k_n, law.k_unload, law.f0, law.kadh, law.n, law.chi
        )
        stiff = tangent * law.k_n
    elif flags.plastic:
        f_el, dmax = bilinear_normal_force(d, dmax, law.k_n, law.k_unload, law.f0, law.kadh)
        stiff = law.k_n
        f_adh = law.kadh * d
    else:  # k2 == k1: no plastic overlap, linear elastic (plus the adhesion offset)
        if d > dmax:
            dmax = d
        f_el = law.f0 + law.k_n * d
        stiff = law.k_n
        f_adh = law.kadh * d
    # 3. damping
    fn = f_el
    if flags.damping:
        fn -= viscous_damping_coefficient(law.zeta, m_eff, stiff) * vn
    ftx = 0.0
    fty = 0.0
    ftz = 0.0
    if flags.friction:
        # 4. friction cap from the normal force
        if flags.normal_cap:
            cap = law.mu_s * abs(fn)
        else:
            cap = friction_limit(law.mu_s, f_el, law.f0, f_adh)
        # 5. tangential spring
        if flags.hertz:
            kt = hertz_tangential_stiffness(d, law.k_t, r_star)
        elif flags.eepa:
            kt = law.k_t * tangent  # kt_ratio x the loading tangent n K1 d^(n-1)
        else:
            kt = law.k_t
        ct = viscous_damping_coefficient(law.zeta, m_eff, kt) if flags.damping else 0.0
        ftx, fty, ftz, xix, xiy, xiz = tangential_spring_force(
            xix, xiy, xiz, nx, ny, nz, vtx, vty, vtz, kt, ct, cap, dt
        )
    return fn, f_el, ftx, fty, ftz, dmax, xix, xiy, xiz


@njit(**NJIT_INLINE)
def contact(hist, k, d, nx, ny, nz, vx, vy, vz, sx, sy, sz, ri, rj, r_star, m_eff, law, flags, dt):
    r"""A contact of the step kernel, pair or wall: :func:`contact_force` on the history row
    ``hist[k]`` (slot 0: largest overlap or contact marker [m]; slots 1-3: tangential spring
    [m], with friction), written back in place, and the torque split.

    Args as :func:`contact_force`, plus the history array and row and the radii ri, rj [m] of
    the two bodies (a wall: rj = 0).
    Returns: (force on i (3) [N], torque on i (3) [N m], torque on j (3) [N m], rolling
    moment ``mu_r |f_el|`` [N] (0 without rolling)). Both bodies turn the same way:
    :math:`t_i = -R_i\,n\times F_t`, :math:`t_j = -R_j\,n\times F_t`.
    """
    xix = 0.0
    xiy = 0.0
    xiz = 0.0
    if flags.friction:
        xix = hist[k, 1]
        xiy = hist[k, 2]
        xiz = hist[k, 3]
    fn, f_el, ftx, fty, ftz, dmax, xix, xiy, xiz = contact_force(
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
