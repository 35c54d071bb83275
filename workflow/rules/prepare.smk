# Stage prepare: settle a packing once; every sim whose packing parameters match shares it. A run is a scene in
# its configured engine (results/<scene>) or in another one for the cross-check (results/crosscheck/<scene>/<engine>).
rule prepare:
    output:
        directory("results/{run}/packings/{key}"),
    params:
        packing=packing_params_json,
        engine=run_engine,
        scene=run_scene,
    log:
        "results/{run}/logs/prepare/{key}.log",
    benchmark:
        "results/{run}/benchmarks/prepare/{key}.tsv"
    shell:
        "graphdem prepare --scene {params.scene} --engine {params.engine} --params {params.packing:q} "
        "--out {output} > {log} 2>&1"
