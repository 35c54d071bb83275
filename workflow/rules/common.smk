# Helpers shared by every rule: the resolved config, the sweep tables, per-job parameters.
import json
import os
import sys

from generators import config as gconfig
from generators import sweep as gsweep
from generators.scenes import slide as slide_scene

# Rules call `graphdem`; make sure it is the one installed beside this Snakemake.
os.environ["PATH"] = os.path.dirname(sys.executable) + os.pathsep + os.environ.get("PATH", "")

try:
    CFG = gconfig.resolve(config)
except gconfig.ConfigError as exc:
    sys.exit(f"graphdem: {exc}")

SCENES = ["slide"]
SWEEPS = {scene: gsweep.build(scene, CFG[scene]) for scene in SCENES}


wildcard_constraints:
    scene="|".join(SCENES),
    sim=r"[a-z]+_\d+",
    key=r"p\d+-[0-9a-f]+",


def _json(value) -> str:
    return json.dumps(value, sort_keys=True)


# Surrogate settings: a change to them retrains, it never reruns the sweep or an engine.
SURROGATE_KEYS = ("model", "train", "evaluate")


def scene_config_json(wildcards) -> str:
    """The scene's DEM and sweep settings (what the sweep table depends on)."""
    return _json({k: v for k, v in CFG[wildcards.scene].items() if k not in SURROGATE_KEYS})


def sim_ids(scene: str) -> list[str]:
    return list(SWEEPS[scene]["id"])


def sim_row(wildcards) -> dict:
    table = SWEEPS[wildcards.scene]
    rows = table[table["id"] == wildcards.sim]
    if rows.empty:
        raise ValueError(f"{wildcards.sim} is not in the {wildcards.scene} sweep "
                         f"({len(table)} sims: {table['id'].iloc[0]}..{table['id'].iloc[-1]})")
    return rows.iloc[0].to_dict()


def sim_row_json(wildcards) -> str:
    """The sim's physics: its sweep row without the split (a new split must not rerun a sim)."""
    row = sim_row(wildcards)
    row.pop("split")
    return _json(row)


def packing_of_sim(wildcards) -> str:
    return f"results/{wildcards.scene}/packings/{sim_row(wildcards)['packing']}"


def packing_params_json(wildcards) -> str:
    cfg = CFG[wildcards.scene]
    for index in range(cfg["n_packings"]):
        params = slide_scene.packing_params(cfg, index)
        if slide_scene.packing_key(params) == wildcards.key:
            return _json(params)
    raise ValueError(f"packing {wildcards.key} does not belong to the current {wildcards.scene} config")


def all_sims(wildcards) -> list[str]:
    return [f"results/{wildcards.scene}/sims/{i}.h5" for i in sim_ids(wildcards.scene)]


def connectivity_radius(wildcards) -> float:
    return CFG[wildcards.scene]["connectivity_radius"]


def test_ids(scene: str) -> list[str]:
    table = SWEEPS[scene]
    return list(table.loc[table["split"] == "test", "id"])


def test_sims(wildcards) -> list[str]:
    return [f"results/{wildcards.scene}/sims/{i}.h5" for i in test_ids(wildcards.scene)]


def test_rollouts(wildcards) -> list[str]:
    return [f"results/{wildcards.scene}/rollouts/{i}.h5" for i in test_ids(wildcards.scene)]


def model_config_json(wildcards) -> str:
    return _json(CFG[wildcards.scene]["model"])


def train_config_json(wildcards) -> str:
    return _json(CFG[wildcards.scene]["train"])


def body_displacement_arg(wildcards) -> str:
    value = CFG[wildcards.scene]["evaluate"]["body_displacement"]
    return "" if value is None else f"--body-displacement {value}"
