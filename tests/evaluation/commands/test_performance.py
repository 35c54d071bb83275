"""`graphdem performance-report` (evaluation/commands/performance.py): the contenders' rows, one CSV each, ranked
into performance.csv with the packings' mean settling time, the Pareto plot and the headline line."""

import math

import pandas as pd
import pytest

from evaluation.commands import performance
from generators import record

from ...command_line import run

CONTENDERS = [
    {"contender": "reference", "kind": "dem", "stable": True, "seconds_per_rollout": 10.0, "mse": 0.0,
     "seconds_per_frame": 1.0, "seconds_per_dem_step": 0.001},
    {"contender": "dt_x4", "kind": "dem", "stable": True, "seconds_per_rollout": 2.5, "mse": 0.5,
     "seconds_per_frame": 0.25, "seconds_per_dem_step": 0.001},
    {"contender": "graphdem", "kind": "surrogate", "stable": True, "seconds_per_rollout": 0.5, "mse": 1.0,
     "seconds_per_frame": 0.05, "seconds_per_dem_step": math.nan},
]


def test_the_report_ranks_the_contenders_and_averages_the_settling(tmp_path, capsys):
    tables = []
    for row in CONTENDERS:
        tables.append(tmp_path / f"{row['contender']}.csv")
        pd.DataFrame([row]).to_csv(tables[-1], index=False)
    packings = []
    for name, seconds in (("p0", 40.0), ("p1", 44.0)):
        run_ = record.EngineRun("lammps", "x", "lmp", seconds)
        (tmp_path / name).mkdir()
        record.write(tmp_path / name / record.RUN_FILE, record.PackingRecord("slide", {}, run_, 1e-4, 1e-3, 10, 5, 1))
        packings.append(str(tmp_path / name))
    run(performance.register, ["performance-report", "--tables", *map(str, tables), "--main", "graphdem",
                               "--reference", "reference", "--packings", *packings, "--out", str(tmp_path / "p.csv"),
                               "--plot", str(tmp_path / "p.png")])
    table = pd.read_csv(tmp_path / "p.csv").set_index("contender")
    # 10 s / 0.5 s = 20x the reference; the fastest DEM with MSE <= 1 is dt_x4, 2.5 s / 0.5 s = 5x; 0.05 s per frame
    # against 1 ms per DEM step: break-even at 50 steps per frame; settling: the mean of 40 s and 44 s
    main = table.loc["graphdem"]
    assert main["speedup_vs_reference"] == pytest.approx(20.0) and main["matched_dem"] == "dt_x4"
    assert main["speedup_vs_matched_dem"] == pytest.approx(5.0) and main["break_even_substeps"] == pytest.approx(50.0)
    assert table.loc["dem_settling", "wall_seconds_per_run"] == 42.0
    assert (tmp_path / "p.png").read_bytes()[:4] == b"\x89PNG"
    out = capsys.readouterr().out
    assert "graphdem: 50.00 ms per frame, 20.0x faster than the DEM reference, 5.00x faster than dt_x4" in out
    assert "break-even at 50 DEM sub-steps per frame" in out
