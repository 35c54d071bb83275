# Stage simulate: one DEM run of the sweep (engine input, log and raw output in raw/<id>/).
rule simulate:
    input:
        packing=packing_of_sim,
        scale=kept_scale,
    output:
        directory("results/{run}/raw/{sim}"),
    threads: simulate_ranks
    params:
        sim=sim_row_json,
        scene=run_scene,
    log:
        "results/{run}/logs/simulate/{sim}.log",
    benchmark:
        "results/{run}/timings/simulate/{sim}.tsv"
    shell:
        "graphdem simulate --scene {params.scene:q} --sim {params.sim:q} "
        "--packing {input.packing:q} --out {output:q} --ranks {threads} > {log} 2>&1"
