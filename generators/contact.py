"""Contact-model arithmetic shared by every engine driver: stiffness, stable time step, damping.

The contact law is a linear spring-dashpot: normal force ``kn * overlap + eta_n * v_n`` with
``eta_n = 2 zeta sqrt(m_eff kn)``, whose coefficient of restitution is independent of mass and
impact speed::

    e = exp(-pi zeta / sqrt(1 - zeta^2))   <=>   zeta = -ln e / sqrt(pi^2 + ln^2 e)
"""

from __future__ import annotations

import math

# Tsuji et al. (1992) polynomial alpha(e); LAMMPS' `damping tsuji` applies
# eta_n = alpha(e_input) * sqrt(m_eff * kn), i.e. zeta = alpha / 2 for a linear (hooke) contact.
_TSUJI = (1.2728, -4.2783, 11.087, -22.348, 27.467, -18.022, 4.8218)


class UnstableTimeStep(ValueError):
    """A configured DEM time step exceeds the stable limit."""


def damping_ratio(restitution: float) -> float:
    """Damping ratio zeta of a linear spring-dashpot that gives ``restitution`` (0 < e <= 1)."""
    if not 0.0 < restitution <= 1.0:
        raise ValueError(f"restitution must be in (0, 1], got {restitution}")
    log_e = math.log(restitution)
    return -log_e / math.sqrt(math.pi**2 + log_e**2)


def restitution_of(zeta: float) -> float:
    """Restitution of a linear spring-dashpot with damping ratio 0 <= zeta < 1."""
    return math.exp(-math.pi * zeta / math.sqrt(1.0 - zeta**2))


def tsuji_alpha(e_input: float) -> float:
    """LAMMPS' Tsuji polynomial alpha(e) as evaluated by `damping tsuji`."""
    return sum(c * e_input**k for k, c in enumerate(_TSUJI))


def lammps_tsuji_input(restitution: float) -> float:
    """The value to give LAMMPS' `hooke ... damping tsuji` so that a linear contact has ``restitution``.

    LAMMPS feeds its input through Tsuji's polynomial (fitted for Hertz contacts), so asking for
    e = 0.5 on a linear contact yields e = 0.58. We solve alpha(e_input) = 2 zeta(e) by bisection;
    alpha is monotonically decreasing on (0, 1].
    """
    target = 2.0 * damping_ratio(restitution)
    lo, hi = 1e-6, 1.0
    if not tsuji_alpha(hi) <= target <= tsuji_alpha(lo):
        raise ValueError(
            f"restitution {restitution} needs Tsuji alpha {target:.4f}, outside LAMMPS' range "
            f"[{tsuji_alpha(hi):.4f}, {tsuji_alpha(lo):.4f}]")
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if tsuji_alpha(mid) > target:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def normal_stiffness(young: float, mean_radius: float, thickness: float = 1.0) -> float:
    """Linear normal stiffness (N/m) of two equal discs: kn = 2 E r1 r2 / (r1 + r2) * t = E r t."""
    return young * mean_radius * thickness


def disc_mass(density: float, radius: float, thickness: float = 1.0) -> float:
    """Mass of a disc of unit thickness (2D scenes)."""
    return density * math.pi * radius**2 * thickness


def sphere_mass(density: float, radius: float) -> float:
    """Mass of a sphere (3D scenes)."""
    return density * 4.0 / 3.0 * math.pi * radius**3


def particle_mass(density: float, radius: float, dim: int) -> float:
    """Mass of a particle of a ``dim``-dimensional scene: a disc of unit thickness (2) or a sphere (3)."""
    return disc_mass(density, radius) if dim == 2 else sphere_mass(density, radius)


def stable_time_step(min_mass: float, kn: float) -> float:
    """Stable limit of velocity Verlet for the stiffest pair contact.

    Two of the lightest particles in contact form an oscillator of reduced mass m/2 and
    stiffness kn; Verlet is stable for omega * dt < 2, so dt_crit = 2 / sqrt(2 kn / m).
    """
    return 2.0 / math.sqrt(2.0 * kn / min_mass)


def choose_time_step(limit: float, safety: float, requested: float | None, where: str) -> float:
    """The DEM step: ``safety * limit`` unless ``requested``; refuse a step above the limit."""
    if requested is None:
        return safety * limit
    if requested > limit:
        raise UnstableTimeStep(
            f"{where}: configured DEM time step dt = {requested:.4g} s exceeds the stable limit "
            f"{limit:.4g} s (= 2/sqrt(2 kn/m_min)); use dt <= {limit:.4g} s or leave dt unset "
            f"for dt_safety * limit")
    return requested


def time_step(cfg: dict, where: str, dim: int) -> tuple[float, float, float]:
    """(dt, stable limit, kn) of a scene's contact: one constant kn = E r_mean in both engines (2 E r1 r2 /
    (r1 + r2) of two particles of the mean radius, per unit thickness in 2D), the limit at two of the
    smallest moving particles (fixed particles have infinite mass; kn / m is largest for the smallest)."""
    kn = normal_stiffness(cfg["young"], 0.5 * (cfg["radius"][0] + cfg["radius"][1]))
    limit = stable_time_step(particle_mass(cfg["density"], cfg["radius"][0], dim), kn)
    return choose_time_step(limit, cfg["dt_safety"], cfg["dt"], where), limit, kn
