"""The direct shear's strength table and Mohr-Coulomb envelopes, on hand-built stress curves with known answers."""

import math
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from generators.scenes import shear_strength


def _sim(young: float, stress: float, peak_ratio: float, residual_ratio: float, frames: int = 20):
    """A curve that rises to peak_ratio x sigma_n at frame 5 and falls to residual_ratio x sigma_n from frame 10; the
    platen sinks 0.1 mm to the peak, then rises to +0.3 mm."""
    tau = np.full(frames, residual_ratio * stress)
    tau[:6] = np.linspace(0, peak_ratio * stress, 6)
    tau[6:10] = np.linspace(peak_ratio * stress, residual_ratio * stress, 5)[1:]
    dz = np.concatenate([np.linspace(0, -1e-4, 6), np.linspace(-1e-4, 3e-4, frames - 6)])
    return SimpleNamespace(parameters={"id": f"s{young:g}_{stress:g}", "young": young, "normal_stress": stress,
                                       "displacement": 0.006, "inertial_number": 9.9e-4},
                           observables={"shear_stress": tau, "normal_displacement": dz,
                                        "shear_displacement": np.linspace(0, 0.006, frames)})


def test_peak_residual_and_dilation_of_one_sim():
    row = shear_strength.strength(_sim(1e7, 1e4, 0.8, 0.5))
    assert row["peak_shear_stress"] == pytest.approx(8e3) and row["peak_ratio"] == pytest.approx(0.8)
    assert row["residual_shear_stress"] == pytest.approx(5e3) and row["residual_ratio"] == pytest.approx(0.5)
    assert row["peak_displacement"] == pytest.approx(0.006 * 5 / 19)
    assert row["dilation_at_peak"] == pytest.approx(-1e-4) and row["dilation_at_end"] == pytest.approx(3e-4)
    assert row["inertial_number"] == 9.9e-4


def test_mohr_coulomb_recovers_friction_angle_and_cohesion():
    stress = np.array([5e3, 1.58e4, 5e4])
    phi, c = shear_strength.mohr_coulomb(stress, 1e3 + stress * math.tan(math.radians(30.0)))
    assert phi == pytest.approx(30.0) and c == pytest.approx(1e3)
    assert all(math.isnan(v) for v in shear_strength.mohr_coulomb(np.array([5e3, 5e3]), np.array([1e3, 2e3])))


def test_envelopes_per_modulus_and_over_all(tmp_path):
    """A purely frictional soil (c = 0): peak ratio tan 35 deg, residual tan 25 deg at every stress; the stiff one
    peaks higher (tan 40 deg)."""
    sims = [_sim(young, stress, math.tan(math.radians(40.0 if young > 5e7 else 35.0)), math.tan(math.radians(25.0)))
            for young in (1e7, 1e8) for stress in (5e3, 1.58e4, 5e4)]
    short = _sim(1e7, 5e3, 2.0, 2.0)                 # sheared less far: not fitted
    short.parameters["displacement"] = 0.003
    sims.append(short)
    out = shear_strength.physics(sims, tmp_path / "physics.csv", tmp_path / "physics.png")
    fits = out[out["sim"] == "fit"].set_index("young")
    assert fits.at["1e+07", "phi_peak_deg"] == pytest.approx(35.0) and fits.at["1e+08", "phi_peak_deg"] == \
        pytest.approx(40.0)
    assert fits.at["all", "phi_residual_deg"] == pytest.approx(25.0)
    assert abs(fits.at["1e+07", "cohesion_peak"]) < 1e-6 and fits.at["all", "sims"] == 6
    assert len(pd.read_csv(tmp_path / "physics.csv")) == 7 + 3
    assert (tmp_path / "physics.png").stat().st_size > 10_000
