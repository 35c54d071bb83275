"""LAMMPS `pair_style granular` parameters of the 2D scenes' linear spring-dashpot contact."""

from __future__ import annotations

import math

from generators import contact


def granular_variables(p: dict, dt: float, limit: float, kn: float) -> dict[str, float]:
    """The `-var` values of the templates' hooke/tsuji/linear_history/sds pair (and wall) coefficients.

    Keys starting with ``_`` are for the driver, not for LAMMPS.
    """
    kt = p["kt_over_kn"] * kn
    r_mean = 0.5 * (p["radius"][0] + p["radius"][1])
    m_mean = contact.disc_mass(p["density"], r_mean)
    zeta = contact.damping_ratio(p["restitution"])
    return {
        "kn": kn, "kt": kt, "kr": kt,
        "e_tsuji": contact.lammps_tsuji_input(p["restitution"]),
        "gammar": 2.0 * zeta * math.sqrt(kt * m_mean / 2.0) * r_mean**2,
        "mu": p["friction"], "mur": p["rolling_friction"],
        "skin": 0.5 * r_mean, "g": p["gravity"], "dt": dt, "density": p["density"],
        "_dt_limit": limit, "_m_mean": m_mean,
    }
