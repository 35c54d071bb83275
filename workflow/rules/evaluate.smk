# Stage evaluate: scene metrics and rollout MSE of Graph-DEM and of constant velocity (docs/surrogate.md).
rule evaluate:
    input:
        checkpoint="results/{scene}/model/best.pt",
        sims=test_sims,
        rollouts=test_rollouts,
    output:
        metrics=report("results/{scene}/metrics.csv", caption="../report/metrics.rst", category="evaluation"),
        per_step="results/{scene}/metrics_per_step.csv",
        frames=report("results/{scene}/plots/metrics_over_frames.png", caption="../report/metrics_over_frames.rst",
                      category="evaluation"),
        gif=report("results/{scene}/plots/rollout.gif", caption="../report/rollout.rst", category="evaluation"),
    params:
        history=history_length,
        body=body_displacement_arg,
    threads: 1
    log:
        "results/{scene}/logs/evaluate.log",
    benchmark:
        "results/{scene}/benchmarks/evaluate.tsv"
    shell:
        "graphdem evaluate --checkpoint {input.checkpoint} --data {input.sims} --split test --history {params.history} "
        "--rollouts results/{wildcards.scene}/rollouts --out {output.metrics} --per-step {output.per_step} "
        "--plots results/{wildcards.scene}/plots {params.body} --no-progress > {log} 2>&1"


# A public benchmark, one protocol (K frames given): roll out every sim of the evaluation split (test,
# or valid where the source has none, which every output then says) and score Graph-DEM beside
# constant velocity. The one model of the benchmark serves every protocol of K >= its history.
rule evaluate_benchmark:
    input:
        checkpoint="results/{bench}/model/best.pt",
        splits="results/{bench}/dataset/splits.csv",
    output:
        metrics="results/{bench}/k{k}/metrics.csv",
        per_step="results/{bench}/k{k}/metrics_per_step.csv",
        frames=report("results/{bench}/k{k}/plots/metrics_over_frames.png", caption="../report/metrics_over_frames.rst",
                      category="benchmarks"),
        gif=report("results/{bench}/k{k}/plots/rollout.gif", caption="../report/rollout.rst", category="benchmarks"),
    params:
        split=benchmark_split,
        runtime=runtime_json,
    threads: 1
    log:
        "results/{bench}/logs/evaluate_k{k}.log",
    benchmark:
        "results/{bench}/benchmarks/evaluate_k{k}.tsv"
    shell:
        "graphdem evaluate --checkpoint {input.checkpoint} --splits {input.splits} --split {params.split} "
        "--history {wildcards.k} --runtime-json {params.runtime:q} --out {output.metrics} --per-step {output.per_step} "
        "--plots results/{wildcards.bench}/k{wildcards.k}/plots --no-progress > {log} 2>&1"


# Both protocols of a benchmark in one table (the `history` column tells them apart).
rule benchmark_metrics:
    input:
        metrics=protocol_metrics,
        per_step=protocol_metrics_per_step,
    output:
        metrics=report("results/{bench}/metrics.csv", caption="../report/benchmark_metrics.rst", category="benchmarks"),
        per_step="results/{bench}/metrics_per_step.csv",
    log:
        "results/{bench}/logs/metrics.log",
    benchmark:
        "results/{bench}/benchmarks/metrics.tsv"
    shell:
        "graphdem combine --tables {input.metrics} --out {output.metrics} > {log} 2>&1 && "
        "graphdem combine --tables {input.per_step} --out {output.per_step} >> {log} 2>&1"
