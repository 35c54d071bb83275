# Stage simulate: one DEM run of the sweep (engine input, log and raw output in raw/<id>/).
rule simulate:
    input:
        packing=packing_of_sim,
    output:
        directory("results/{scene}/raw/{sim}"),
    params:
        sim=sim_row_json,
    log:
        "results/{scene}/logs/simulate/{sim}.log",
    benchmark:
        "results/{scene}/benchmarks/simulate/{sim}.tsv"
    shell:
        "graphdem simulate --scene {wildcards.scene} --sim {params.sim:q} "
        "--packing {input.packing} --out {output} > {log} 2>&1"
