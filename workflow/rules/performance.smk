# Stage performance: run time against error (results/{scene}/performance.csv), for every registered scene. One job
# per contender, each alone on the machine (performance.alone: threads = all cores, so no two timings overlap).
rule performance_dem:
    input:
        truth=timed_sims,
        packings=timed_packings,
    output:
        "results/{scene}/performance/dem/{contender}.csv",
    params:
        variant=contender_json("dem"),
        sims=timed_rows_json,
        history=history_length,
        repeats=stage_setting("performance", "repeats"),
        metrics=metric_args,
    threads: contender_threads("dem")
    log:
        "results/{scene}/logs/performance/dem_{contender}.log",
    benchmark:
        "results/{scene}/timings/performance/dem_{contender}.tsv"
    shell:
        "graphdem performance-dem --scene {wildcards.scene} --name {wildcards.contender} --variant {params.variant:q} "
        "--sims {params.sims:q} --packings results/{wildcards.scene}/packings --truth {input.truth:q} "
        "--history {params.history:q} --repeats {params.repeats:q} {params.metrics:q} --out {output:q} > {log} 2>&1"


rule performance_surrogate:
    input:
        checkpoint="results/{scene}/model/best.pt",
        truth=timed_sims,
    output:
        "results/{scene}/performance/surrogate/{contender}.csv",
    params:
        variant=contender_json("surrogate"),
        runtime=runtime_json,
        repeats=stage_setting("performance", "repeats"),
        threads=stage_setting("performance", "threads"),
        metrics=metric_args,
        device=device_arg,
    threads: contender_threads("surrogate")
    resources:
        gpus=job_gpus,
    log:
        "results/{scene}/logs/performance/surrogate_{contender}.log",
    benchmark:
        "results/{scene}/timings/performance/surrogate_{contender}.tsv"
    shell:
        "graphdem performance-surrogate --name {wildcards.contender} --variant {params.variant:q} "
        "--checkpoint {input.checkpoint:q} --data {input.truth:q} --runtime-json {params.runtime:q} "
        "--threads {params.threads:q} --repeats {params.repeats:q} {params.metrics:q} {params.device:q} "
        "--out {output:q} > {log} 2>&1"


rule performance:
    input:
        tables=contender_tables,
        packings=timed_packings,
    output:
        table=report("results/{scene}/performance.csv", caption="../report/performance.rst",
                     category=report_category, subcategory="performance",
                     labels={"figure": "performance.csv (download)", "scene": "{scene}"}),
        plot=report("results/{scene}/plots/pareto.png", caption="../report/performance.rst",
                    category=report_category, subcategory="performance",
                    labels={"figure": "run time against error (Pareto front)", "scene": "{scene}"}),
        substeps=report("results/{scene}/plots/speedup_substeps.png", caption="../report/performance.rst",
                        category=report_category, subcategory="performance",
                        labels={"figure": "speed-up against DEM sub-steps per frame", "scene": "{scene}"}),
        map="results/{scene}/performance_map.csv",
        map_plot=report("results/{scene}/plots/performance_map.png", caption="../report/performance.rst",
                        category=report_category, subcategory="performance",
                        labels={"figure": "where the surrogate pays, per test sim", "scene": "{scene}"}),
    params:
        main=stage_setting("performance", "main"),
        reference=stage_setting("performance", "reference"),
    log:
        "results/{scene}/logs/performance.log",
    benchmark:
        "results/{scene}/timings/performance.tsv"
    shell:
        "graphdem performance-report --tables {input.tables:q} --packings {input.packings:q} --main {params.main:q} "
        "--reference {params.reference:q} --out {output.table:q} --plot {output.plot:q} --substeps-plot {output.substeps:q} "
        "--map {output.map:q} --map-plot {output.map_plot:q} "
        "--title '{wildcards.scene}: run time against error' > {log} 2>&1"


# The README's pays table (results/performance_pays.csv): a row per scene, from every scene's map; asking for it runs
# each scene's performance stage.
rule performance_pays:
    input:
        maps=expand("results/{scene}/performance_map.csv", scene=SCENES),
    output:
        "results/performance_pays.csv",
    log:
        "results/logs/performance_pays.log",
    benchmark:
        "results/timings/performance_pays.tsv"
    shell:
        "graphdem performance-pays --maps {input.maps:q} --out {output:q} > {log} 2>&1"
