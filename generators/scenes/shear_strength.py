"""The direct shear's strength from its DEM data (the physics stage of the shear scene): per sim the peak and the
residual shear stress, the dilation and the recorded inertial number; over the swept normal stresses the
Mohr-Coulomb envelope tau = c + sigma_n tan(phi) of the peak and of the residual, per modulus and over all sims.

The residual is the mean shear stress over the last ``RESIDUAL_SHARE`` of the recorded frames (the plateau a
direct shear test reports as its residual or critical-state strength). Published context: frictional spheres
(interparticle friction about 0.5, no rolling resistance) reach a critical-state friction angle of about 21-24
degrees in DEM (Thornton 2000; GDR MiDi 2004, mu_s = 0.38 for glass beads), a dense packing a higher peak.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import pandas as pd

RESIDUAL_SHARE = 0.2      # the residual: the mean over the last 20 % of the recorded frames
MIN_STRESSES = 2          # normal stresses a Mohr-Coulomb fit needs


def strength(traj) -> dict:
    """One sim's row: its sweep values, recorded inertial number, peak and residual shear stress (Pa) and their
    ratios to the set normal stress, and the dilation (m, the platen's rise) at the peak and at the end."""
    p, o = traj.parameters, traj.observables
    tau = np.asarray(o["shear_stress"], float)
    n = max(1, int(math.ceil(RESIDUAL_SHARE * len(tau))))
    peak = int(np.nanargmax(tau))
    residual = float(np.mean(tau[-n:]))
    stress = float(p["normal_stress"])
    dilation = np.asarray(o["normal_displacement"], float)
    return {"sim": str(p.get("id")), "young": float(p["young"]), "normal_stress": stress,
            "displacement": float(p["displacement"]), "inertial_number": float(p.get("inertial_number", np.nan)),
            "peak_shear_stress": float(tau[peak]), "peak_displacement": float(o["shear_displacement"][peak]),
            "residual_shear_stress": residual, "peak_ratio": float(tau[peak]) / stress,
            "residual_ratio": residual / stress, "dilation_at_peak": float(dilation[peak]),
            "dilation_at_end": float(dilation[-1])}


def mohr_coulomb(stress: np.ndarray, tau: np.ndarray) -> tuple[float, float]:
    """(phi in degrees, cohesion c in Pa) of the least-squares line tau = c + sigma_n tan(phi); NaN where fewer
    than MIN_STRESSES distinct normal stresses are given."""
    stress, tau = np.asarray(stress, float), np.asarray(tau, float)
    if len(np.unique(stress)) < MIN_STRESSES:
        return float("nan"), float("nan")
    slope, cohesion = np.polyfit(stress, tau, 1)
    return float(math.degrees(math.atan(slope))), float(cohesion)


def envelopes(table: pd.DataFrame) -> pd.DataFrame:
    """Fit rows (``sim`` = ``fit``): per modulus and over all moduli (``young`` = all), the peak's and the residual's
    friction angle and cohesion, and the number of sims. Only the sims sheared to the sweep's largest displacement
    are fitted: a shorter one may end before its peak (its last frames are no residual)."""
    import pandas as pd
    table = table[table["displacement"] == table["displacement"].max()]
    groups = [(f"{young:g}", part) for young, part in table.groupby("young")] + [("all", table)]
    rows = []
    for young, part in groups:
        phi_peak, c_peak = mohr_coulomb(part["normal_stress"], part["peak_shear_stress"])
        phi_res, c_res = mohr_coulomb(part["normal_stress"], part["residual_shear_stress"])
        rows.append({"sim": "fit", "young": young, "sims": len(part), "phi_peak_deg": phi_peak,
                     "cohesion_peak": c_peak, "phi_residual_deg": phi_res, "cohesion_residual": c_res})
    return pd.DataFrame(rows)


def plot(table: pd.DataFrame, fits: pd.DataFrame, path: Path) -> None:
    """The peak and residual shear stress of every sim against its normal stress, with the envelope over all
    sims."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from generators.atomic import atomic_path
    fig, ax = plt.subplots(figsize=(7, 4.8), constrained_layout=True)
    every = fits[fits["young"] == "all"].iloc[0]
    s = np.linspace(0, table["normal_stress"].max() * 1.1, 50)
    for column, phi, c, colour in (("peak_shear_stress", "phi_peak_deg", "cohesion_peak", "#d43d2a"),
                                   ("residual_shear_stress", "phi_residual_deg", "cohesion_residual", "#2a6fd4")):
        name = column.split("_")[0]
        ax.plot(table["normal_stress"] / 1e3, table[column] / 1e3, "o", color=colour, ms=4, label=f"DEM {name}")
        if np.isfinite(every[phi]):
            ax.plot(s / 1e3, (every[c] + s * math.tan(math.radians(every[phi]))) / 1e3, color=colour, lw=1,
                    label=f"{name}: phi = {every[phi]:.1f} deg, c = {every[c] / 1e3:.2f} kPa")
    ax.set_xlabel("normal stress sigma_n (kPa)")
    ax.set_ylabel("shear stress tau (kPa)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("direct shear: Mohr-Coulomb envelopes of the DEM data (all moduli)", fontsize=10)
    with atomic_path(Path(path)) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)


def physics(trajectories: list, out_csv: Path, out_png: Path) -> pd.DataFrame:
    """The strength table (a row per sim, then the fit rows) written to ``out_csv``, its plot to ``out_png``."""
    import pandas as pd

    from generators.atomic import atomic_path
    table = pd.DataFrame([strength(t) for t in trajectories]).sort_values(["young", "normal_stress", "displacement"])
    table = table.reset_index(drop=True)
    fits = envelopes(table)
    out = pd.concat([table, fits], ignore_index=True)
    with atomic_path(Path(out_csv)) as tmp:
        out.to_csv(tmp, index=False)
    plot(table, fits, out_png)
    return out
