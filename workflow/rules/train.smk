# Stage train: Graph-DEM on the train split, best checkpoint by validation rollout MSE.
# last.pt (the full training state) is written beside the outputs but is not one of them, so
# Snakemake never deletes it: rerunning an interrupted job continues where it stopped.
rule train:
    input:
        stats="results/{scene}/dataset/stats.json",
        splits="results/{scene}/dataset/splits.csv",
        sims=all_sims,
    output:
        best="results/{scene}/model/best.pt",
        history="results/{scene}/model/history.csv",
    params:
        model=model_config_json,
        train=train_config_json,
    threads: 64  # Snakemake caps this at --cores: training takes every core it is given
    log:
        "results/{scene}/logs/train.log",
    benchmark:
        "results/{scene}/benchmarks/train.tsv"
    shell:
        "graphdem train --stats {input.stats} --splits {input.splits} --model-json {params.model:q} "
        "--train-json {params.train:q} --out-dir results/{wildcards.scene}/model --threads {threads} > {log} 2>&1"


# A public benchmark trains one model (history length `B.model.history`), scored under every protocol.
# One thread: graphs of ~100 particles gain little from a second core, so under -c2 the two
# benchmarks train side by side.
rule train_benchmark:
    input:
        stats="results/{bench}/dataset/stats.json",
        splits="results/{bench}/dataset/splits.csv",
    output:
        best="results/{bench}/model/best.pt",
        history="results/{bench}/model/history.csv",
    params:
        model=model_config_json,
        train=train_config_json,
    threads: 1
    log:
        "results/{bench}/logs/train.log",
    benchmark:
        "results/{bench}/benchmarks/train.tsv"
    shell:
        "graphdem train --stats {input.stats} --splits {input.splits} --model-json {params.model:q} "
        "--train-json {params.train:q} --out-dir results/{wildcards.bench}/model "
        "--threads {threads} --no-progress > {log} 2>&1"
