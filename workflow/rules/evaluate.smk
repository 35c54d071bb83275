# Stage evaluate: scene metrics and rollout MSE of Graph-DEM beside constant velocity (docs/surrogate.md).
# A scene scores its test sims from the rollout stage; a public benchmark rolls out its evaluation split
# (test, or valid where the source has none, which every output then says) under each protocol K.
# metrics.html is metrics.csv as the report's table, every empty cell named n/a or undefined; metrics.config.json
# the model config its rows name by config_sha (written by graphdem evaluate beside --out).
rule evaluate:
    input:
        checkpoint="results/{name}/model/best.pt",
        splits="results/{name}/dataset/splits.csv",
        rollouts=evaluated_rollouts,
        ensemble=ensemble_sims,
    output:
        metrics=report("results/{name}/metrics.csv", caption="../report/metrics.rst",
                       category=report_category, subcategory="evaluation",
                       labels={"figure": "metrics.csv (download)", "scene": "{name}"}),
        table=report("results/{name}/metrics.html", caption="../report/metrics_table.rst",
                     category=report_category, subcategory="evaluation",
                     labels={"figure": "metrics table", "scene": "{name}"}),
        per_step="results/{name}/metrics_per_step.csv",
        config="results/{name}/metrics.config.json",      # the config metrics.csv's config_sha names
        frames=report("results/{name}/plots/metrics_over_frames.png", caption="../report/metrics_over_frames.rst",
                      category=report_category, subcategory="evaluation",
                      labels={"figure": "metrics over frames", "scene": "{name}"}),
        gif=report("results/{name}/plots/rollout.gif", caption="../report/rollout.rst",
                   category=report_category, subcategory="evaluation",
                   labels={"figure": "rollout animation (GIF, a download)", "scene": "{name}"}),
    params:
        evaluation=evaluation_args,
        runtime=runtime_json,
        metrics=metric_args,
        device=device_arg,
    threads: 1
    resources:
        gpus=job_gpus,
    log:
        "results/{name}/logs/evaluate.log",
    benchmark:
        "results/{name}/timings/evaluate.tsv"
    shell:
        "graphdem evaluate --checkpoint {input.checkpoint:q} --splits {input.splits:q} {params.evaluation:q} "
        "--runtime-json {params.runtime:q} --out {output.metrics:q} --table-html {output.table:q} "
        "--per-step {output.per_step:q} "
        "--plots results/{wildcards.name}/plots {params.metrics:q} {params.device:q} --no-progress > {log} 2>&1"
