# Stage prepare: settle a packing once; every sim whose packing parameters match shares it (in every engine:
# the cross-check's other engine starts from the same packings).
rule prepare:
    input:
        kept_scale,
    output:
        directory("results/{scene}/packings/{key}"),
    threads: prepare_ranks
    params:
        packing=packing_params_json,
        engine=scene_engine,
    log:
        "results/{scene}/logs/prepare/{key}.log",
    benchmark:
        "results/{scene}/timings/prepare/{key}.tsv"
    shell:
        "graphdem prepare --scene {wildcards.scene} --engine {params.engine:q} --params {params.packing:q} "
        "--out {output:q} --ranks {threads} > {log} 2>&1"
