# Stage sweep: one row per simulation with every concrete DEM parameter and its seed.
rule sweep:
    input:
        kept_scale,
    output:
        "results/{scene}/sweep.csv",
    params:
        cfg=scene_config_json,
    log:
        "results/{scene}/logs/sweep.log",
    benchmark:
        "results/{scene}/timings/sweep.tsv"
    shell:
        "graphdem sweep --scene {wildcards.scene} --config-json {params.cfg:q} --out {output:q} > {log} 2>&1"
