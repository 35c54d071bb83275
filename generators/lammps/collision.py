"""Measure the contact model in LAMMPS with head-on two-disc collisions.

LAMMPS' `damping tsuji` maps its input through a polynomial fitted for Hertz contacts; the
drivers invert that map exactly for a linear contact (contact.lammps_tsuji_input). What remains
is time discretisation: a contact resolved by ~16 steps (dt_safety 0.1) scatters the measured
restitution by up to 10 %; at dt_safety 0.01 (~157 steps) it is within 1 %. Tests measure it.
"""

from __future__ import annotations

import math
import re
import tempfile
from pathlib import Path

from generators import contact
from generators.lammps import runner


def collision_restitution(e_input: float, young: float, radius: float, density: float, dt: float,
                          kt_over_kn: float, speed: float = 1.0, friction: float = 0.0,
                          kn_radius: float | None = None) -> float:
    """Rebound / impact speed of two equal discs of ``radius`` colliding head-on at +-``speed``.

    ``kn_radius`` is the radius the scene's stiffness is based on (kn = young * kn_radius).
    """
    kn = contact.normal_stiffness(young, kn_radius or radius)
    mass = contact.disc_mass(density, radius)
    contact_time = math.pi / math.sqrt(2 * kn / mass)
    variables = {
        "kn": kn, "e_tsuji": e_input, "kt": kt_over_kn * kn, "mu": friction,
        "kr": kt_over_kn * kn, "gammar": 0.0, "mur": 0.0,
        "radius": radius, "density": density, "speed": speed, "dt": dt,
        "nsteps": int((0.1 * radius / speed + 3 * contact_time) / dt),
    }
    with tempfile.TemporaryDirectory() as tmp:
        runner.run("collision.in", variables, Path(tmp))
        text = (Path(tmp) / "log.lammps").read_text()
    v_left, v_right = map(float, re.findall(r"VELOCITIES (\S+) (\S+)", text)[-1])
    return (v_right - v_left) / (2 * speed)
