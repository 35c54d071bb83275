"""Energy check shared by the LAMMPS scenes (2D, y up): a recorded run must not gain energy."""

from __future__ import annotations

import numpy as np
import pandas as pd

from generators import stability
from generators.lammps import io


def check_energy(sim: str, raw: dict, thermo: pd.DataFrame, row: dict) -> np.ndarray:
    """Kinetic (thermo, translational + rotational) plus gravitational energy of the moving particles
    at the recorded frames must not grow (stability.check_energy); returns the kinetic energy per
    frame."""
    thermo = thermo.drop_duplicates("Step", keep="last").set_index("Step")
    missing = sorted(set(raw["step"].tolist()) - set(thermo.index.astype(int).tolist()))
    if missing:
        raise io.LammpsOutputError(f"{sim}: no thermo output at recorded steps {missing[:3]}")
    kinetic = (thermo["c_ke"] + thermo["c_erot"]).loc[raw["step"]].to_numpy()
    soil = ~raw["kinematic"]
    mass = raw["mass"][soil]
    potential = row["gravity"] * (raw["position"][:, soil, 1] * mass).sum(axis=1)
    scale = row["gravity"] * mass.sum() * 2.0 * raw["radius"][soil].mean()
    stability.check_energy(sim, kinetic, potential, scale, row["max_energy_gain"])
    return kinetic
