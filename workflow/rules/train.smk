# Stage train: Graph-DEM on the train split, best checkpoint by validation rollout MSE (a public
# benchmark trains one model, history `B.model.history`, scored under every protocol).
# last.pt (the full training state) is written beside the outputs but is not one of them, so
# Snakemake never deletes it: rerunning an interrupted job continues where it stopped.
# The config's launch section starts it as one process or as torchrun's processes (DDP), on `device`
# (docs/scaling.md); threads are shared among the processes.
rule train:
    input:
        stats="results/{name}/dataset/stats.json",
        splits="results/{name}/dataset/splits.csv",
        sims=all_sims,
    output:
        best="results/{name}/model/best.pt",
        history="results/{name}/model/history.csv",
    params:
        model=model_config_json,
        train=train_config_json,
        progress=progress_arg,
        command=train_command,
        device=device_arg,
    threads: train_threads
    resources:
        gpus=train_gpus,
    log:
        "results/{name}/logs/train.log",
    benchmark:
        "results/{name}/timings/train.tsv"
    shell:
        "{params.command:q} train --stats {input.stats:q} --splits {input.splits:q} --model-json {params.model:q} "
        "--train-json {params.train:q} --out-dir results/{wildcards.name}/model --threads {threads} "
        "{params.device:q} {params.progress:q} > {log} 2>&1"
