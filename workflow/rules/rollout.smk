# Stage rollout: the predicted trajectory of one test sim, same H5MD layout as the sims.
rule rollout:
    input:
        checkpoint="results/{scene}/model/best.pt",
        sim="results/{scene}/sims/{sim}.h5",
    output:
        "results/{scene}/rollouts/{sim}.h5",
    params:
        runtime=runtime_json,
        device=device_arg,
    threads: 1
    resources:
        gpus=job_gpus,
    log:
        "results/{scene}/logs/rollout/{sim}.log",
    benchmark:
        "results/{scene}/timings/rollout/{sim}.tsv"
    shell:
        "graphdem rollout --checkpoint {input.checkpoint:q} --data {input.sim:q} "
        "--out-dir results/{wildcards.scene}/rollouts --threads {threads} --runtime-json {params.runtime:q} "
        "{params.device:q} > {log} 2>&1"
