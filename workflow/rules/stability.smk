# Stage stability: stability tests of the DEM (time step at multiples of the stable limit) and of the
# surrogate (long rollouts from a perturbed history, three precisions) on the first test sims.
rule stability_dem:
    input:
        packing=stability_packing,
    output:
        "results/{scene}/stability/dem.csv",
    params:
        sim=stability_row_json,
        factors=stage_setting("stability", "dem_dt_factors"),
    threads: 1
    log:
        "results/{scene}/logs/stability_dem.log",
    benchmark:
        "results/{scene}/timings/stability_dem.tsv"
    shell:
        "graphdem stability-dem --scene {wildcards.scene} --sim {params.sim:q} --packing {input.packing:q} "
        "--factors {params.factors:q} --out {output:q} > {log} 2>&1"


rule stability_surrogate:
    input:
        checkpoint="results/{scene}/model/best.pt",
        sims=stability_sims,
    output:
        table="results/{scene}/stability/surrogate.csv",
        frames="results/{scene}/stability/frames.csv",
        plot=report("results/{scene}/plots/stability.png", caption="../report/stability.rst",
                    category=report_category, subcategory="stability",
                    labels={"figure": "long rollouts: energy and overlaps per frame", "scene": "{scene}"}),
    params:
        runtime=runtime_json,
        args=surrogate_stability_args,
        device=device_arg,
    threads: 1
    resources:
        gpus=job_gpus,
    log:
        "results/{scene}/logs/stability_surrogate.log",
    benchmark:
        "results/{scene}/timings/stability_surrogate.tsv"
    shell:
        "graphdem stability-surrogate --checkpoint {input.checkpoint:q} --data {input.sims:q} "
        "--runtime-json {params.runtime:q} {params.args:q} {params.device:q} "
        "--out {output.table:q} --frames-out {output.frames:q} --plot {output.plot:q} "
        "--title {wildcards.scene:q} > {log} 2>&1"


rule stability:
    input:
        dem="results/{scene}/stability/dem.csv",
        surrogate="results/{scene}/stability/surrogate.csv",
    output:
        report("results/{scene}/stability.csv", caption="../report/stability.rst",
               category=report_category, subcategory="stability",
               labels={"figure": "stability.csv (download)", "scene": "{scene}"}),
    log:
        "results/{scene}/logs/stability.log",
    benchmark:
        "results/{scene}/timings/stability.tsv"
    shell:
        "graphdem combine --union --tables {input.dem:q} {input.surrogate:q} --out {output:q} > {log} 2>&1"
