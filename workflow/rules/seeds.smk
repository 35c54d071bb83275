# Stage seeds: the scene or benchmark trained with `seeds` seeds (train.seed, train.seed + 1, ...), each model
# scored by the evaluate stage's evaluation (metrics.csv and, per frame, metrics_per_step.csv), and every metric's
# mean and spread (results/<name>/seeds.csv;
# docs/surrogate.md, "Seeds"). The first seed is the main model (results/<name>/model); the others live in
# results/<name>/seeds/<seed>/. Only built when asked for: `snakemake -c2 results/slide/seeds.csv`.
rule train_seed:
    input:
        stats="results/{name}/dataset/stats.json",
        splits="results/{name}/dataset/splits.csv",
        sims=all_sims,
    output:
        best="results/{name}/seeds/{seed}/model/best.pt",
        history="results/{name}/seeds/{seed}/model/history.csv",
    params:
        model=model_config_json,
        train=seed_train_config_json,
        progress=progress_arg,
        command=train_command,
        device=device_arg,
    threads: train_threads
    resources:
        gpus=train_gpus,
    log:
        "results/{name}/seeds/{seed}/logs/train.log",
    benchmark:
        "results/{name}/seeds/{seed}/timings/train.tsv"
    shell:
        "{params.command:q} train --stats {input.stats:q} --splits {input.splits:q} --model-json {params.model:q} "
        "--train-json {params.train:q} --out-dir results/{wildcards.name}/seeds/{wildcards.seed}/model "
        "--threads {threads} {params.device:q} {params.progress:q} > {log} 2>&1"


rule evaluate_seed:
    input:
        checkpoint="results/{name}/seeds/{seed}/model/best.pt",
        splits="results/{name}/dataset/splits.csv",
        ensemble=ensemble_sims,
    output:
        metrics="results/{name}/seeds/{seed}/metrics.csv",
        per_step="results/{name}/seeds/{seed}/metrics_per_step.csv",
        config="results/{name}/seeds/{seed}/metrics.config.json",      # the config metrics.csv's config_sha names
    params:
        evaluation=seed_evaluation_args,
        runtime=runtime_json,
        metrics=metric_args,
        device=device_arg,
    threads: 1
    resources:
        gpus=job_gpus,
    log:
        "results/{name}/seeds/{seed}/logs/evaluate.log",
    benchmark:
        "results/{name}/seeds/{seed}/timings/evaluate.tsv"
    shell:
        "graphdem evaluate --checkpoint {input.checkpoint:q} --splits {input.splits:q} {params.evaluation:q} "
        "--runtime-json {params.runtime:q} --out {output.metrics:q} --per-step {output.per_step:q} "
        "{params.metrics:q} {params.device:q} --no-progress > {log} 2>&1"


# The seed ensemble: every seed's model as one simulator integrating their mean acceleration (surrogate/ensemble.py),
# scored by the seeds' evaluation; the benchmark card reads it beside the seeds (docs/benchmarks.md, "Benchmark card").
rule evaluate_seed_ensemble:
    input:
        checkpoints=seed_checkpoints,
        splits="results/{name}/dataset/splits.csv",
        ensemble=ensemble_sims,
    output:
        metrics="results/{name}/seed_ensemble/metrics.csv",
        per_step="results/{name}/seed_ensemble/metrics_per_step.csv",
        config="results/{name}/seed_ensemble/metrics.config.json",      # the config metrics.csv's config_sha names
    params:
        evaluation=seed_evaluation_args,
        runtime=runtime_json,
        metrics=metric_args,
        device=device_arg,
    threads: 1
    resources:
        gpus=job_gpus,
    log:
        "results/{name}/seed_ensemble/logs/evaluate.log",
    benchmark:
        "results/{name}/seed_ensemble/timings/evaluate.tsv"
    shell:
        "graphdem evaluate --checkpoint {input.checkpoints:q} --splits {input.splits:q} {params.evaluation:q} "
        "--runtime-json {params.runtime:q} --out {output.metrics:q} --per-step {output.per_step:q} "
        "{params.metrics:q} {params.device:q} --no-progress > {log} 2>&1"


rule seeds:
    input:
        seed_metrics,
    output:
        report("results/{name}/seeds.csv", caption="../report/seeds.rst", category=report_category,
               subcategory="evaluation", labels={"figure": "seeds.csv (download)", "scene": "{name}"}),
    params:
        seeds=seed_list,
    log:
        "results/{name}/logs/seeds.log",
    benchmark:
        "results/{name}/timings/seeds.tsv"
    shell:
        "graphdem seeds --metrics {input:q} --seeds {params.seeds:q} --out {output:q} > {log} 2>&1"
