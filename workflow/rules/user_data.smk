# User data (docs/user-data.md): any folder of H5MD sims (config key user_data), under results/<name>/ like a scene.
# Its own stages are the dataset (the folder split here, not by a sweep or an import) and the rollout of each test
# sim (read from the folder); training and evaluation are the shared rules' (train.smk, evaluate.smk), with the
# config's `user` section and the generic metrics only (no DEM ensemble: no engine config exists for user data).


# Every user-data set of the config (none by default, so a target of its own, as the benchmarks'):
# `snakemake -c2 user_data --config user_data='{a: /data/a, b: /data/b}'`.
rule user_data:
    input:
        expand("results/{name}/metrics.csv", name=USER_DATA),
        expand("results/{name}/metrics.html", name=USER_DATA),


# Stage dataset of a user-data set: the folder's sims split by user.split (seeded by user.seed), each checked to hold
# a training sample's frames, the train split's statistics, R derived where user.connectivity_radius is auto.
rule dataset_user:
    input:
        sims=user_sims,
        scale=kept_scale,
    output:
        splits="results/{name}/dataset/splits.csv",
        stats="results/{name}/dataset/stats.json",
        plot=report("results/{name}/plots/dataset_sample.png", caption="../report/dataset.rst",
                    category=report_category, subcategory="dataset",
                    labels={"figure": "dataset sample (first and last frame)", "scene": "{name}"}),
    params:
        folder=user_folder,
        settings=user_dataset_args,
    wildcard_constraints:
        name=USER_NAMES,
    log:
        "results/{name}/logs/dataset.log",
    benchmark:
        "results/{name}/timings/dataset.tsv"
    shell:
        "graphdem dataset --user-data {params.folder:q} {params.settings:q} "
        "--out-dir results/{wildcards.name}/dataset --plot {output.plot:q} > {log} 2>&1"


# Stage rollout of a user-data set: the predicted trajectory of one test sim, as the scenes' rollout stage.
rule rollout_user:
    input:
        checkpoint="results/{name}/model/best.pt",
        sim=user_sim,
    output:
        "results/{name}/rollouts/{sim}.h5",
    params:
        runtime=runtime_json,
        device=device_arg,
    wildcard_constraints:
        name=USER_NAMES,
        sim=guser.NAME.pattern.strip("^$"),
    threads: 1
    resources:
        gpus=job_gpus,
    log:
        "results/{name}/logs/rollout/{sim}.log",
    benchmark:
        "results/{name}/timings/rollout/{sim}.tsv"
    shell:
        "graphdem rollout --checkpoint {input.checkpoint:q} --data {input.sim:q} "
        "--out-dir results/{wildcards.name}/rollouts --threads {threads} --runtime-json {params.runtime:q} "
        "{params.device:q} > {log} 2>&1"
