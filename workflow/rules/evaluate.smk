# Stage evaluate: scene metrics and rollout MSE of Graph-DEM beside constant velocity (docs/surrogate.md).
# A scene scores its test sims from the rollout stage; a public benchmark rolls out its evaluation split
# (test, or valid where the source has none, which every output then says) under each protocol K.
rule evaluate:
    input:
        checkpoint="results/{name}/model/best.pt",
        splits="results/{name}/dataset/splits.csv",
        rollouts=evaluated_rollouts,
    output:
        metrics=report("results/{name}/metrics.csv", caption="../report/metrics.rst", category="evaluation"),
        per_step="results/{name}/metrics_per_step.csv",
        frames=report("results/{name}/plots/metrics_over_frames.png", caption="../report/metrics_over_frames.rst",
                      category="evaluation"),
        gif=report("results/{name}/plots/rollout.gif", caption="../report/rollout.rst", category="evaluation"),
    params:
        evaluation=evaluation_args,
        runtime=runtime_json,
        body=body_displacement_arg,
        device=device_arg,
    threads: 1
    resources:
        gpus=job_gpus,
    log:
        "results/{name}/logs/evaluate.log",
    benchmark:
        "results/{name}/benchmarks/evaluate.tsv"
    shell:
        "graphdem evaluate --checkpoint {input.checkpoint:q} --splits {input.splits:q} {params.evaluation:q} "
        "--runtime-json {params.runtime:q} --out {output.metrics:q} --per-step {output.per_step:q} "
        "--plots results/{wildcards.name}/plots {params.body:q} {params.device:q} --no-progress > {log} 2>&1"
