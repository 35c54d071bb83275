# Helpers shared by every rule: the resolved config, the scene registry's sweep tables, per-job parameters.
# Scenes (generators/scenes/) and the public benchmarks (Solid-GN, imported) share the dataset, train and
# evaluate rules through the wildcard `name`; input functions here give each its inputs. User-data sets (any folder
# of H5MD sims; workflow/rules/user_data.smk) share the train and evaluate rules the same way.
import json
import os
import re
import sys
from pathlib import Path

from generators import config as gconfig
from generators import property_sensitivity as gproperty
from generators import engines as gengines
from generators import ensemble as gensemble
from generators import scenes as gscenes
from generators import sweep as gsweep
from generators import user_data as guser
from generators.packing import packing_key
from generators.scene import EXECUTION_KEYS, SURROGATE_KEYS

# The workflow's own helpers (launcher, locks, report guard, scale stamps) are workflow/graphdem_workflow/, not
# part of the installed packages: only this Snakefile uses them.
if workflow.basedir not in sys.path:
    sys.path.insert(0, workflow.basedir)
from graphdem_workflow import launch as glaunch
from graphdem_workflow import locks as glocks
from graphdem_workflow import report as greport
from graphdem_workflow import scales as gscales
from graphdem_workflow import targets as gtargets

# Rules call `graphdem`; make sure it is the one installed beside this Snakemake.
os.environ["PATH"] = os.path.dirname(sys.executable) + os.pathsep + os.environ.get("PATH", "")

# A run killed with SIGKILL leaves its locks: with no other Snakemake working here, the same command resumes.
if glocks.remove_stale_locks(Path.cwd()):
    print("graphdem: removed the locks of a killed Snakemake run (no other Snakemake works in this folder)",
          file=sys.stderr)

try:
    CFG = gconfig.load(config)           # the package's defaults, with --config / --configfile on top
except gconfig.ConfigError as exc:
    sys.exit(f"graphdem: {exc}")

SCENES = gscenes.names()
ENGINES = gengines.names()             # the engine registry (generators/engines.py)
# A run: a scene in its configured engine (results/<scene>/), in another engine for the cross-check
# (results/crosscheck/<scene>/<engine>/), on the same sweep rows from the same settled packings, or in its
# configured engine from packings perturbed by crosscheck.perturbation radii (results/crosscheck/<scene>/chaos/).
CROSSCHECK_RUNS = [f"crosscheck/{s}/{e}" for s in SCENES for e in ENGINES if e != CFG[s]["engine"]]
CROSSCHECK_RUNS += [f"crosscheck/{s}/chaos" for s in SCENES]


def ensemble_members(scene: str) -> int:
    """The DEM ensemble's members per test sim of ``scene``: evaluate.ensemble_members, 0 (none) where
    evaluate.ensemble_perturbation is null."""
    section = CFG[scene]["evaluate"]
    return 0 if section["ensemble_perturbation"] is None else int(section["ensemble_members"])


# The DEM ensemble (results/<scene>/ensemble/m<j>/, member j = 0..evaluate.ensemble_members - 1): each test sim's
# run replayed by its configured engine to its last history frame K - 1, every moving particle displaced there by
# evaluate.ensemble_perturbation radii, and run on (generators/ensemble.py); scored beside Graph-DEM (the chaos floor).
ENSEMBLE_RUNS = [f"{s}/ensemble/m{j}" for s in SCENES for j in range(ensemble_members(s))]
# The property-sensitivity test's reruns (results/<scene>/property/<i>/, article Fig. 14): the scene's test sims
# rerun by its configured engine with one node property at its i-th value (evaluate.property_sensitivity;
# generators/property_sensitivity.py).
PROPERTY_VALUES = {s: gproperty.values(s, CFG[s]) for s in SCENES}
PROPERTY_RUNS = [f"{s}/property/{i}" for s in SCENES for i in range(len(PROPERTY_VALUES[s]))]
SWEEPS = {scene: gsweep.build(scene, CFG[scene]) for scene in SCENES}
# Scenes whose section has a shear_stress_readout (the shear stress read from predicted frames;
# workflow/rules/shear_stress.smk).
SHEAR_STRESS_SCENES = [s for s in SCENES if "shear_stress_readout" in CFG[s]]
# Public benchmarks (article Table 6), imported from solidgn_root rather than simulated.
BENCHMARKS = list(gconfig.BENCHMARKS)
# User-data sets (config key user_data; docs/user-data.md): results name -> folder of H5MD sims, each trained and
# scored with the config's `user` section, split as its dataset stage splits it (generators/user_data.py).
USER_DATA = CFG["user_data"]
USER_SPLITS = {name: guser.split_table(folder, CFG["user"]["split"], CFG["user"]["seed"])
               for name, folder in USER_DATA.items()}
# The `name` of the rules only scenes and benchmarks have, and of those only user-data sets have ((?!): none).
SCENE_OR_BENCHMARK = "|".join(SCENES + BENCHMARKS)
USER_NAMES = "|".join(re.escape(name) for name in USER_DATA) or "(?!)"
# The results folders this run involves (filled while the DAG is built); each records the run's scale.
SCALE_FOLDERS = set()


wildcard_constraints:
    scene="|".join(SCENES),
    run="|".join(SCENES + CROSSCHECK_RUNS + ENSEMBLE_RUNS + PROPERTY_RUNS),
    engine="|".join(ENGINES),
    bench="|".join(BENCHMARKS),
    name="|".join(SCENES + BENCHMARKS + [re.escape(name) for name in USER_DATA]),
    sim=r"[a-z]+_\d+",
    key=r"p\d+-[0-9a-f]+",
    seed=r"\d+",
    value=r"\d+",


def report_category(wildcards) -> str:
    """A result's category in snakemake --report: its scene or public benchmark (the subcategory is the
    stage). Snakemake calls this only while it builds a report, before adding the first result, so it
    first refuses a report whose jobs never ran under the report's config (workflow/graphdem_workflow/report.py)."""
    greport.check(workflow.dag)
    return getattr(wildcards, "scene", None) or wildcards.name


def _json(value) -> str:
    return json.dumps(value, sort_keys=True)


def kept_scale(wildcards) -> list[str]:
    """Input function of the stages that start a scene's results (sweep, prepare, simulate, also of the
    cross-check's runs), a benchmark's (import) or a user-data set's (its dataset): no input, but refuses a run at
    another scale than the results folder records (workflow/graphdem_workflow/scales.py), before anything runs."""
    name = (getattr(wildcards, "scene", None) or getattr(wildcards, "bench", None) or getattr(wildcards, "name", None)
            or run_scene(wildcards))
    folder = f"results/{name}"
    gscales.check(folder, CFG["scale"], CFG["overwrite_scale"])
    SCALE_FOLDERS.add(folder)
    return []


def record_scales() -> None:
    """When a run starts: every results folder it involves now holds the run's scale."""
    for folder in sorted(SCALE_FOLDERS):
        gscales.record(folder, CFG["scale"])


def is_scene(wildcards) -> bool:
    return wildcards.name in SCENES


def is_user_data(wildcards) -> bool:
    return wildcards.name in USER_DATA


def section_name(name: str) -> str:
    """The config section of a results name: the scene's or benchmark's own, `user` for a user-data set."""
    return "user" if name in USER_DATA else name


def scene_or_benchmark_option(wildcards) -> list[str]:
    """A job's scene or public benchmark as the option `graphdem` takes it: --scene or --benchmark."""
    return ["--scene" if is_scene(wildcards) else "--benchmark", wildcards.name]


def scene_config_json(wildcards) -> str:
    """The scene's DEM and sweep settings (what the sweep table depends on: not how an engine runs)."""
    return _json({k: v for k, v in CFG[wildcards.scene].items() if k not in (*SURROGATE_KEYS, *EXECUTION_KEYS)})


def scene_engine(wildcards) -> str:
    return CFG[wildcards.scene]["engine"]


def run_scene(wildcards) -> str:
    """The scene of a run (results/<scene>, results/<scene>/ensemble/m<j>, results/<scene>/property/<i> or
    results/crosscheck/<scene>/<engine>)."""
    parts = wildcards.run.split("/")
    return parts[1] if parts[0] == "crosscheck" else parts[0]


def run_engine(wildcards) -> str:
    """The engine of a run: the cross-check's other engine, or the scene's configured one."""
    parts = wildcards.run.split("/")
    return parts[2] if len(parts) == 3 and parts[2] in ENGINES else CFG[run_scene(wildcards)]["engine"]


def _ranks(scene: str, engine: str) -> int:
    """The MPI ranks of a run of ``scene`` in ``engine``: its `ranks` key where the engine takes more cores as MPI
    ranks (LAMMPS), else 1 (one process: YADE)."""
    return CFG[scene]["ranks"] if gengines.takes_ranks(engine) else 1


def prepare_ranks(wildcards) -> int:
    """`threads:` of a prepare job: the ranks its engine runs on (Snakemake caps them at --cores, and the
    job runs on the threads it is given)."""
    return _ranks(wildcards.scene, scene_engine(wildcards))


def simulate_ranks(wildcards) -> int:
    """`threads:` of a simulate job: the ranks of the run's engine (capped at --cores, as prepare's)."""
    return _ranks(run_scene(wildcards), run_engine(wildcards))


def run_dir(scene: str, engine: str) -> str:
    """Where a scene's run in ``engine`` lives: its own folder for the configured engine."""
    return f"results/{scene}" if engine == CFG[scene]["engine"] else f"results/crosscheck/{scene}/{engine}"


def sim_ids(scene: str) -> list[str]:
    return list(SWEEPS[scene]["id"])


def _row(scene: str, sim: str) -> dict:
    table = SWEEPS[scene]
    rows = table[table["id"] == sim]
    if rows.empty:
        raise ValueError(f"{sim} is not in the {scene} sweep "
                         f"({len(table)} sims: {table['id'].iloc[0]}..{table['id'].iloc[-1]})")
    return rows.iloc[0].to_dict()


def _physics(scene: str, sim: str) -> dict:
    """A sim's physics: its sweep row without the split (a new split must not rerun a sim)."""
    row = _row(scene, sim)
    row.pop("split")
    return row


def ensemble_row(scene: str, run: str) -> dict:
    """What a DEM ensemble member's run (results/<scene>/ensemble/m<j>) adds to its sim's row: the member j, the
    frame it is perturbed after (the last history frame, K - 1) and the displacement in radii."""
    return {gensemble.MEMBER: int(run.rsplit("/m", 1)[1]), gensemble.FRAME: CFG[scene]["model"]["history"] - 1,
            gensemble.SIZE: CFG[scene]["evaluate"]["ensemble_perturbation"]}


def sim_row_json(wildcards) -> str:
    """A run's sim: the scene's sweep row in the run's engine (perturbed in a chaos run, replayed and perturbed
    at the last history frame in a DEM ensemble member's run, one property at the run's value in a
    property-sensitivity run)."""
    scene = run_scene(wildcards)
    row = {**_physics(scene, wildcards.sim), "engine": run_engine(wildcards)}
    if wildcards.run.endswith("/chaos"):
        row["perturbation"] = CFG["crosscheck"]["perturbation"]
    elif wildcards.run in ENSEMBLE_RUNS:
        row.update(ensemble_row(scene, wildcards.run))
    elif wildcards.run in PROPERTY_RUNS:
        prop = CFG[scene]["evaluate"]["property_sensitivity"]["property"]
        row[prop] = PROPERTY_VALUES[scene][int(wildcards.run.split("/")[2])]
    return _json(row)


def packing_of_sim(wildcards) -> str:
    """The sim's settled packing: part of its sweep row, so the cross-check's other engine starts from the
    same one (settled by the scene's configured engine; docs/crosscheck.md)."""
    scene = run_scene(wildcards)
    return f"results/{scene}/packings/{_row(scene, wildcards.sim)['packing']}"


def packing_params_json(wildcards) -> str:
    for params in gscenes.get(wildcards.scene).packings(CFG[wildcards.scene]):
        if packing_key(params) == wildcards.key:
            return _json(params)
    raise ValueError(f"packing {wildcards.key} does not belong to the current {wildcards.scene} config")


def all_sims(wildcards) -> list[str]:
    scene = getattr(wildcards, "scene", None) or wildcards.name
    return [f"results/{scene}/sims/{i}.h5" for i in sim_ids(scene)] if scene in SCENES else []


def _section(wildcards) -> dict:
    """The config section of a job's scene, public benchmark or user-data set."""
    return CFG[section_name(getattr(wildcards, "scene", None) or wildcards.name)]


def connectivity_radius(wildcards) -> float:
    return _section(wildcards)["connectivity_radius"]


def test_ids(scene: str) -> list[str]:
    table = SWEEPS[scene]
    return list(table.loc[table["split"] == "test", "id"])


def model_config_json(wildcards) -> str:
    """The model config (a benchmark's one model is scored under every protocol K >= its history). A null
    `max_neighbours` (no cap: the graph as before the key existed) is left out, so that the train jobs of
    models trained before it are not rerun for a changed parameter; the simulator reads a missing cap as none."""
    model = _section(wildcards)["model"]
    return _json({k: v for k, v in model.items() if not (k == "max_neighbours" and v is None)})


def train_config_json(wildcards) -> str:
    return _json(_section(wildcards)["train"])


def runtime_json(wildcards) -> str:
    """The runtime switches of a scene or benchmark (surrogate/runtime.py)."""
    return _json(_section(wildcards)["runtime"])


# Arguments that are optional or many are lists: a rule writes them as {params.x:q}, every item quoted.


def body_displacement_arg(wildcards) -> list[str]:
    value = _section(wildcards).get("evaluate", {}).get("body_displacement")
    return [] if value is None else ["--body-displacement", str(value)]


def metric_args(wildcards) -> list[str]:
    """The scene metrics' settings (`evaluate` section): the body threshold and the article-style Acc's frames."""
    section = _section(wildcards).get("evaluate", {})
    value, frames = section.get("body_displacement"), section.get("frames")
    return ([] if value is None else ["--body-displacement", str(value)]) + \
        ([] if frames is None else ["--frames", *map(str, frames)])


def history_length(wildcards) -> int:
    return _section(wildcards)["model"]["history"]


# ---- the stages scenes and public benchmarks share -------------------------------------------------


def dataset_table(wildcards) -> str:
    """The split table a dataset is built from: the sweep (scenes) or the import's (public benchmarks)."""
    return f"results/{wildcards.name}/sweep.csv" if is_scene(wildcards) else f"results/{wildcards.name}/import/splits.csv"


def train_threads(wildcards) -> int:
    """Scenes and user-data sets train on every core given; a public benchmark on one (graphs of ~100 particles
    gain little from a second core, so under -c2 the two benchmarks train side by side)."""
    return 1 if wildcards.name in BENCHMARKS else 64    # Snakemake caps threads at --cores


def progress_arg(wildcards) -> list[str]:
    return [] if is_scene(wildcards) else ["--no-progress"]


# ---- where the surrogate computes (config keys device and launch; docs/scaling.md) ------------------
# Machine settings: the arguments are recorded by Snakemake as one constant, so changing them reruns no job.


def device_arg(wildcards) -> list[str]:
    """--device with the config's device, for every surrogate job that computes."""
    return glaunch.device_args(CFG)


def train_command(wildcards) -> list[str]:
    """graphdem, or torchrun starting launch.processes training processes on the node."""
    return glaunch.train_command(CFG)


def job_gpus(wildcards) -> int:
    """The gpus resource of a surrogate job: 1 with device cuda or cuda:N, else 0."""
    return glaunch.gpus(CFG)


def train_gpus(wildcards) -> int:
    """The gpus resource of the train job: one per training process with device cuda or cuda:N, else 0."""
    return glaunch.train_gpus(CFG)


def rollout_paths(scene: str, ids: list[str]) -> list[str]:
    """The rollout stage's files of a scene's sims ``ids`` (one job per sim)."""
    return [f"results/{scene}/rollouts/{i}.h5" for i in ids]


def evaluated_rollouts(wildcards) -> list[str]:
    """A scene's or user-data set's test rollouts (the rollout stage, one job per sim); a public benchmark rolls
    out inside evaluate, once per protocol."""
    if is_user_data(wildcards):
        return rollout_paths(wildcards.name, user_test_ids(wildcards.name))
    if not is_scene(wildcards):
        return []
    return rollout_paths(wildcards.name, test_ids(wildcards.name))


# ---- seeds (results/<name>/seeds.csv) -----------------------------------------------------------------


def _seeds(name: str) -> list[int]:
    """The training seeds of a scene, benchmark or user-data set: train.seed and the next `seeds` - 1."""
    first = int(CFG[section_name(name)]["train"]["seed"])
    return list(range(first, first + int(CFG["seeds"])))


def seed_list(wildcards) -> list[str]:
    return [str(s) for s in _seeds(wildcards.name)]


def seed_metrics(wildcards) -> list[str]:
    """Each seed's metrics.csv: the main model's for the first seed, results/<name>/seeds/<seed>/ for the rest."""
    first, *rest = _seeds(wildcards.name)
    return [f"results/{wildcards.name}/metrics.csv", *(f"results/{wildcards.name}/seeds/{s}/metrics.csv" for s in rest)]


def seed_checkpoints(wildcards) -> list[str]:
    """Each seed's best.pt, in seed_metrics' order: the models of the seed ensemble."""
    first, *rest = _seeds(wildcards.name)
    return [f"results/{wildcards.name}/model/best.pt", *(f"results/{wildcards.name}/seeds/{s}/model/best.pt" for s in rest)]


def seed_ensemble_tables(wildcards) -> dict[str, str]:
    """The seed ensemble's metrics.csv and metrics_per_step.csv, which the card reads with two or more seeds."""
    if len(_seeds(wildcards.name)) < 2:
        return {}
    folder = f"results/{wildcards.name}/seed_ensemble"
    return {"ensemble_metrics": f"{folder}/metrics.csv", "ensemble_steps": f"{folder}/metrics_per_step.csv"}


def seed_train_config_json(wildcards) -> str:
    """The train config with the seed of the job."""
    return _json({**_section(wildcards)["train"], "seed": int(wildcards.seed)})


def seed_evaluation_args(wildcards) -> list[str]:
    """A seed's evaluation: the evaluate stage's, rolling out inside the job (no rollout files per seed)."""
    args = evaluation_args(wildcards)
    if "--rollouts" in args:
        at = args.index("--rollouts")
        del args[at:at + 2]
    return args


def seed_per_step(wildcards) -> list[str]:
    """Each seed's metrics_per_step.csv, in seed_metrics' order."""
    first, *rest = _seeds(wildcards.name)
    return [f"results/{wildcards.name}/metrics_per_step.csv",
            *(f"results/{wildcards.name}/seeds/{s}/metrics_per_step.csv" for s in rest)]


def seed_histories(wildcards) -> list[str]:
    """Each seed's model/history.csv (its training time and where it ran), in seed_metrics' order."""
    first, *rest = _seeds(wildcards.name)
    return [f"results/{wildcards.name}/model/history.csv",
            *(f"results/{wildcards.name}/seeds/{s}/model/history.csv" for s in rest)]


# ---- benchmark card (results/<bench>/card.csv, card.md) -------------------------------------------


def article_json(wildcards) -> str:
    """The article's figures of a public benchmark (its `article` section), shown beside ours."""
    return _json(CFG[wildcards.name]["article"])


def card_ensemble_args(wildcards) -> list[str]:
    """--ensemble-metrics and --ensemble-steps of the seed ensemble (none with one seed)."""
    tables = seed_ensemble_tables(wildcards)
    return [] if not tables else ["--ensemble-metrics", tables["ensemble_metrics"],
                                  "--ensemble-steps", tables["ensemble_steps"]]


def card_machine_args(wildcards) -> list[str]:
    """The device setting the jobs were given and the threads the train rule asks for (a benchmark's one): said
    on the card, and assumed for a history.csv that does not record where its model trained. Machine settings,
    recorded as one constant (changing them remakes no card)."""
    return glaunch.MachineArgs([*glaunch.device_args(CFG), "--train-threads", str(train_threads(wildcards))])


def ensemble_dirs(scene: str) -> list[str]:
    """The DEM ensemble's member folders of ``scene`` (<sim id>.h5 per test sim in each), member 0 first; none
    without an ensemble."""
    return [f"results/{scene}/ensemble/m{j}/sims" for j in range(ensemble_members(scene))]


def ensemble_sims(wildcards) -> list[str]:
    """Every DEM ensemble member of a scene's test sims (none without an ensemble, or for a public benchmark,
    whose engine runs are not ours to repeat)."""
    if not is_scene(wildcards):
        return []
    return [f"{folder}/{i}.h5" for folder in ensemble_dirs(wildcards.name) for i in test_ids(wildcards.name)]


def first_member_sims(wildcards) -> list[str]:
    """Member 0 of the DEM ensemble of a scene's test sims: the one rerun the property-sensitivity test and the
    shear-stress check set beside the sims (none without an ensemble)."""
    return [f"{folder}/{i}.h5" for folder in ensemble_dirs(wildcards.name)[:1] for i in test_ids(wildcards.name)]


def _property_runs(scene: str) -> list[str]:
    """The property-sensitivity test's run folders of ``scene``, low value first."""
    return [f"results/{scene}/property/{i}" for i in range(len(PROPERTY_VALUES[scene]))]


def property_sensitivity_inputs(wildcards) -> dict[str, list[str]]:
    """The property-sensitivity test's reruns and their rollouts (low value first), and the sims and DEM ensemble
    whose difference is the chaos its signal stands beside (none without an ensemble)."""
    scene, ids = wildcards.scene, test_ids(wildcards.scene)
    if not PROPERTY_VALUES[scene]:
        raise ValueError(f"the {scene} scene has no property-sensitivity test: set "
                         f"'{scene}.evaluate.property_sensitivity' (docs/surrogate.md, Property sensitivity)")
    runs = _property_runs(scene)
    inputs = {"sims": [f"{run}/sims/{i}.h5" for run in runs for i in ids],
              "rollouts": [f"{run}/rollouts/{i}.h5" for run in runs for i in ids]}
    if ensemble_members(scene):
        folders = (f"results/{scene}/sims", ensemble_dirs(scene)[0])
        inputs["chaos"] = [f"{folder}/{i}.h5" for folder in folders for i in ids]
    return inputs


def test_sims(wildcards) -> list[str]:
    """A scene's test sims' files."""
    return [f"results/{wildcards.name}/sims/{i}.h5" for i in test_ids(wildcards.name)]


def shear_stress_readout_json(wildcards) -> str:
    """The scene's shear_stress_readout settings (the readout's training), as JSON."""
    return json.dumps(CFG[wildcards.name]["shear_stress_readout"])


def shear_stress_check_args(wildcards) -> list[str]:
    """The rollouts, K, tolerance and (where the scene has one) DEM ensemble of the shear-stress check."""
    scene = wildcards.name
    chaos = ["--ensemble", *ensemble_dirs(scene)[:1]] if ensemble_members(scene) else []
    return ["--rollouts", f"results/{scene}/rollouts", "--history", str(history_length(wildcards)),
            "--tolerance", str(CFG[scene]["shear_stress_readout"]["tolerance"]), *chaos]


def property_sensitivity_args(wildcards) -> list[str]:
    """The runs, sims, property, K and tolerance of the property-sensitivity test (and the chaos' folders)."""
    scene = wildcards.scene
    test = CFG[scene]["evaluate"]["property_sensitivity"]
    chaos = []
    if ensemble_members(scene):
        chaos = ["--sims-dir", f"results/{scene}/sims", "--ensemble", ensemble_dirs(scene)[0]]
    return ["--runs", *_property_runs(scene),
            "--sims", *test_ids(scene), "--property", test["property"],
            "--history", str(history_length(wildcards)), "--tolerance", str(test["tolerance"]), *chaos]


def evaluation_args(wildcards) -> list[str]:
    """The split, protocols, rollouts, DEM ensemble and bootstrap intervals of the evaluate stage (a user-data set:
    a scene's, without the ensemble)."""
    intervals = ["--intervals-json", _json(CFG["intervals"])]
    if wildcards.name not in BENCHMARKS:
        ensemble = ["--ensemble", *ensemble_dirs(wildcards.name)] if ensemble_sims(wildcards) else []
        return ["--split", "test", "--history", str(history_length(wildcards)),
                "--rollouts", f"results/{wildcards.name}/rollouts", *ensemble, *intervals]
    bench = CFG[wildcards.name]
    return ["--split", bench["evaluate"]["split"], "--history", *(str(k) for k in bench["protocols"]), *intervals]


# ---- cross-check ---------------------------------------------------------------------------------


def crosscheck_ids(scene: str) -> list[str]:
    """The sweep rows both engines run: the first crosscheck.sims of the sweep (all where null)."""
    n = CFG["crosscheck"]["sims"]
    return sim_ids(scene)[:n] if n is not None else sim_ids(scene)


def crosscheck_sims(engine: str):
    """Input function: the cross-checked sims of the scene in ``engine``."""
    def sims(wildcards) -> list[str]:
        return [f"{run_dir(wildcards.scene, engine)}/sims/{i}.h5" for i in crosscheck_ids(wildcards.scene)]
    return sims


def crosscheck_engine_args(wildcards, input) -> list[str]:
    """`graphdem crosscheck`'s sims of each engine, as its options: --<engine> FILES for every registered one."""
    return [arg for engine in ENGINES for arg in (f"--{engine}", *input[engine])]


def other_engine(wildcards) -> str:
    """The engine a scene is cross-checked in (the one it is not configured for)."""
    return next(e for e in ENGINES if e != CFG[wildcards.scene]["engine"])


def transfer_other_metrics(wildcards) -> str:
    return f"results/crosscheck/{wildcards.scene}/transfer_{other_engine(wildcards)}_metrics.csv"


def chaos_sims(wildcards) -> list[str]:
    """The configured engine's reruns of the cross-checked rows from perturbed packings."""
    return [f"results/crosscheck/{wildcards.scene}/chaos/sims/{i}.h5" for i in crosscheck_ids(wildcards.scene)]


def transfer_sims(wildcards) -> list[str]:
    """The other engine's runs of the scene's test sims (the transfer score)."""
    return [f"{run_dir(wildcards.scene, wildcards.engine)}/sims/{i}.h5" for i in test_ids(wildcards.scene)]


# ---- public benchmarks ---------------------------------------------------------------------------


def solidgn_metadata(wildcards) -> str:
    """metadata.json of the benchmark's Solid-GN folder; stops with what to set when it is missing."""
    root = CFG.get("solidgn_root")
    if not root:
        raise ValueError(
            f"{wildcards.bench} needs the Solid-GN data: set the config key 'solidgn_root' to the folder holding "
            f"Slide_Same_R/ and Slide/, e.g. snakemake -c2 results/{wildcards.bench}/metrics.csv "
            f"--config solidgn_root=/path/to/solidgn")
    source = os.path.join(root, CFG[wildcards.bench]["source"])
    metadata = os.path.join(source, "metadata.json")
    if not os.path.isfile(metadata):
        raise ValueError(
            f"config key 'solidgn_root' = {root!r}: {source} has no metadata.json; solidgn_root must be the "
            f"folder holding {CFG[wildcards.bench]['source']}/ (with metadata.json, train/ and valid/ of .pkl files)")
    return metadata


def solidgn_source(wildcards, input) -> str:
    return os.path.dirname(input.metadata)


def solidgn_limits(wildcards) -> list[str]:
    sims = CFG[wildcards.bench]["sims"]
    return [arg for split, n in sims.items() if n is not None for arg in ("--limit", f"{split}={n}")]


# ---- stability and performance stages ------------------------------------------------------------


def stage_config(scene: str, stage: str) -> dict:
    """The scene's config section of a stage every scene has (stability, performance)."""
    return CFG[scene][stage]


def stage_setting(stage: str, key: str):
    """Input function: one setting of the scene's ``stage`` section."""
    def setting(wildcards):
        return stage_config(wildcards.scene, stage)[key]
    return setting


def _first_test_ids(wildcards, stage: str) -> list[str]:
    ids = test_ids(wildcards.scene)
    if not ids:
        raise ValueError(f"{wildcards.scene}: the sweep has no test sim for the {stage} stage")
    return ids[: stage_config(wildcards.scene, stage)["sims"]]


def stability_ids(wildcards) -> list[str]:
    """The test sims of the stability tests (the first stability.sims)."""
    return _first_test_ids(wildcards, "stability")


def stability_sims(wildcards) -> list[str]:
    return [f"results/{wildcards.scene}/sims/{i}.h5" for i in stability_ids(wildcards)]


def stability_packing(wildcards) -> str:
    first = stability_ids(wildcards)[0]
    return f"results/{wildcards.scene}/packings/{_row(wildcards.scene, first)['packing']}"


def stability_row_json(wildcards) -> str:
    return _json(_physics(wildcards.scene, stability_ids(wildcards)[0]))


def surrogate_stability_args(wildcards) -> list[str]:
    s = stage_config(wildcards.scene, "stability")
    return ["--lengths", *(str(n) for n in s["rollout_lengths"]), "--noise", str(s["history_noise"]),
            "--seed", str(s["seed"]), "--max-overlap", str(CFG[wildcards.scene]["max_overlap"]),
            "--energy-envelope", str(s["energy_envelope"])]


def timed_ids(wildcards) -> list[str]:
    """The test sims the performance stage times (the first performance.sims)."""
    return _first_test_ids(wildcards, "performance")


def timed_sims(wildcards) -> list[str]:
    return [f"results/{wildcards.scene}/sims/{i}.h5" for i in timed_ids(wildcards)]


def timed_rows_json(wildcards) -> str:
    return _json([_physics(wildcards.scene, i) for i in timed_ids(wildcards)])


def timed_packings(wildcards) -> list[str]:
    keys = dict.fromkeys(_row(wildcards.scene, i)["packing"] for i in timed_ids(wildcards))
    return [f"results/{wildcards.scene}/packings/{k}" for k in keys]


def contender_json(kind: str):
    """Input function: the changes of one performance contender of ``kind`` (dem or surrogate)."""
    def changes(wildcards) -> str:
        contenders = stage_config(wildcards.scene, "performance")[kind]
        if wildcards.contender not in contenders:
            raise ValueError(f"{wildcards.scene}: no {kind} contender {wildcards.contender!r} in "
                             f"performance.{kind}; configured: {sorted(contenders)}")
        return _json(contenders[wildcards.contender])
    return changes


def contender_threads(kind: str):
    """Input function: the cores of a performance job. With performance.alone (the default) every core
    the run has (capped by -c), so no two timings overlap; otherwise the contender's own: its cores (DEM)
    or torch threads (surrogate)."""
    def threads(wildcards) -> int:
        perf = stage_config(wildcards.scene, "performance")
        if perf["alone"]:
            return 64
        changes = perf[kind].get(wildcards.contender, {})
        return int(changes.get("cores", 1)) if kind == "dem" else int(changes.get("threads", perf["threads"]))
    return threads


def contender_tables(wildcards) -> list[str]:
    b = stage_config(wildcards.scene, "performance")
    return [f"results/{wildcards.scene}/performance/{kind}/{name}.csv" for kind in ("dem", "surrogate")
            for name in b[kind]]


# ---- ParaView export -----------------------------------------------------------------------------


def export_ids(wildcards) -> list[str]:
    """The sims a scene exports for ParaView: its test sims, each with its rollout."""
    ids = test_ids(wildcards.scene)
    if not ids:
        raise ValueError(f"results/{wildcards.scene}/vtk: the {wildcards.scene} sweep has no test sim to export")
    return ids


def export_sims(wildcards) -> list[str]:
    return [f"results/{wildcards.scene}/sims/{i}.h5" for i in export_ids(wildcards)]


def export_rollouts(wildcards) -> list[str]:
    return rollout_paths(wildcards.scene, export_ids(wildcards))


# ---- user data (workflow/rules/user_data.smk) ---------------------------------------------------------


def user_test_ids(name: str) -> list[str]:
    """The test sims of a user-data set (its split table, generators/user_data.py)."""
    table = USER_SPLITS[name]
    return list(table.loc[table["split"] == "test", "id"])


def user_folder(wildcards) -> str:
    return USER_DATA[wildcards.name]


def user_sims(wildcards) -> list[str]:
    """Every sim of a user-data set's folder: the dataset stage reads each (a changed sim remakes the dataset)."""
    return list(USER_SPLITS[wildcards.name]["path"])


def user_sim(wildcards) -> str:
    """The file of one sim of a user-data set."""
    table = USER_SPLITS[wildcards.name]
    rows = table.loc[table["id"] == wildcards.sim, "path"]
    if rows.empty:
        raise ValueError(f"{wildcards.sim} is not a sim of the user-data set {wildcards.name} "
                         f"({USER_DATA[wildcards.name]}: {len(table)} sims)")
    return rows.iloc[0]


def user_dataset_args(wildcards) -> list[str]:
    """The split (fractions, seed), the frames a sim must hold (history + bundle) and the graph radius of a
    user-data set's dataset stage: R itself, or where `auto`, the mean diameters it is derived from."""
    user = CFG["user"]
    model = user["model"]
    radius = user["connectivity_radius"]
    graph = (["--connectivity-diameters", str(user["connectivity_diameters"])] if radius == "auto"
             else ["--connectivity-radius", str(radius)])
    return ["--fractions", *map(str, user["split"]), "--seed", str(user["seed"]),
            "--min-frames", str(model["history"] + model.get("bundle", 1)), *graph]
