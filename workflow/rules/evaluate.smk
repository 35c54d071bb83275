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
        history=lambda wc: CFG[wc.scene]["model"]["history"],
        body=body_displacement_arg,
    threads: 1
    log:
        "results/{scene}/logs/evaluate.log",
    benchmark:
        "results/{scene}/benchmarks/evaluate.tsv"
    shell:
        "graphdem evaluate --checkpoint {input.checkpoint} --data {input.sims} --history {params.history} "
        "--rollouts results/{wildcards.scene}/rollouts --out {output.metrics} --per-step {output.per_step} "
        "--plots results/{wildcards.scene}/plots {params.body} --no-progress > {log} 2>&1"
