# Stage crosscheck: the scene's sweep rows run in every registered engine (LAMMPS and YADE), each scene metric
# compared for each pair of engines over the sims beside the DEM's own chaos (the configured engine from perturbed packings; docs/crosscheck.md); and the transfer score of the scene's model on the other engine's test sims.
rule crosscheck:
    input:
        **{engine: crosscheck_sims(engine) for engine in ENGINES},
        chaos=chaos_sims,
    output:
        "results/crosscheck/{scene}.csv",
    params:
        sims=crosscheck_engine_args,
        tolerance=CFG["crosscheck"]["tolerance"],
        body=body_displacement_arg,
    log:
        "results/crosscheck/logs/{scene}.log",
    benchmark:
        "results/crosscheck/timings/{scene}.tsv"
    shell:
        "graphdem crosscheck --scene {wildcards.scene} {params.sims:q} --chaos {input.chaos:q} "
        "--tolerance {params.tolerance:q} {params.body:q} --out {output:q} > {log} 2>&1"


rule crosscheck_all:
    input:
        expand("results/crosscheck/{scene}.csv", scene=SCENES),
    output:
        "results/crosscheck.csv",
    log:
        "results/crosscheck/logs/all.log",
    benchmark:
        "results/crosscheck/timings/all.tsv"
    shell:
        "graphdem crosscheck --combine {input:q} --out {output:q} > {log} 2>&1"


rule transfer_evaluate:
    input:
        checkpoint="results/{scene}/model/best.pt",
        sims=transfer_sims,
    output:
        metrics="results/crosscheck/{scene}/transfer_{engine}_metrics.csv",
        config="results/crosscheck/{scene}/transfer_{engine}_metrics.config.json",   # its config_sha's config
    params:
        history=history_length,
        runtime=runtime_json,
        metrics=metric_args,
    threads: 1
    log:
        "results/crosscheck/{scene}/logs/transfer_{engine}.log",
    benchmark:
        "results/crosscheck/{scene}/timings/transfer_{engine}.tsv"
    shell:
        "graphdem evaluate --checkpoint {input.checkpoint:q} --data {input.sims:q} --split test --history {params.history:q} "
        "--runtime-json {params.runtime:q} {params.metrics:q} --out {output.metrics:q} --no-progress > {log} 2>&1"


rule transfer:
    input:
        same="results/{scene}/metrics.csv",
        other=transfer_other_metrics,
    output:
        "results/crosscheck/{scene}_transfer.csv",
    params:
        trained_on=scene_engine,
        other=other_engine,
    log:
        "results/crosscheck/logs/{scene}_transfer.log",
    benchmark:
        "results/crosscheck/timings/{scene}_transfer.tsv"
    shell:
        "graphdem transfer --same {input.same:q} --other {input.other:q} --trained-on {params.trained_on:q} "
        "--other-engine {params.other:q} --out {output:q} > {log} 2>&1"
