# Stage benchmark: run time against error. One job per contender, each alone on the machine
# (threads = all cores, so no two timings overlap); the torch thread count is benchmark.threads.
rule benchmark_dem:
    input:
        truth=benchmarked_sims,
        packings=benchmarked_packings,
    output:
        "results/{scene}/benchmark/dem/{contender}.csv",
    params:
        variant=contender_json("dem"),
        sims=benchmarked_rows_json,
        history=history_length,
        repeats=stage_setting("benchmark", "repeats"),
        body=body_displacement_arg,
    threads: 64
    log:
        "results/{scene}/logs/benchmark/dem_{contender}.log",
    benchmark:
        "results/{scene}/benchmarks/benchmark/dem_{contender}.tsv"
    shell:
        "graphdem benchmark-dem --scene {wildcards.scene} --name {wildcards.contender} --variant {params.variant:q} "
        "--sims {params.sims:q} --packings results/{wildcards.scene}/packings --truth {input.truth} "
        "--history {params.history} --repeats {params.repeats} {params.body} --out {output} > {log} 2>&1"


rule benchmark_surrogate:
    input:
        checkpoint="results/{scene}/model/best.pt",
        truth=benchmarked_sims,
    output:
        "results/{scene}/benchmark/surrogate/{contender}.csv",
    params:
        variant=contender_json("surrogate"),
        runtime=runtime_json,
        repeats=stage_setting("benchmark", "repeats"),
        threads=stage_setting("benchmark", "threads"),
        body=body_displacement_arg,
    threads: 64
    log:
        "results/{scene}/logs/benchmark/surrogate_{contender}.log",
    benchmark:
        "results/{scene}/benchmarks/benchmark/surrogate_{contender}.tsv"
    shell:
        "graphdem benchmark-surrogate --name {wildcards.contender} --variant {params.variant:q} "
        "--checkpoint {input.checkpoint} --data {input.truth} --runtime-json {params.runtime:q} "
        "--threads {params.threads} --repeats {params.repeats} {params.body} --out {output} > {log} 2>&1"


rule benchmark:
    input:
        tables=contender_tables,
        packings=benchmarked_packings,
    output:
        table=report("results/{scene}/benchmark.csv", caption="../report/benchmark.rst", category="benchmark"),
        plot=report("results/{scene}/plots/pareto.png", caption="../report/benchmark.rst", category="benchmark"),
    params:
        main=stage_setting("benchmark", "main"),
        reference=stage_setting("benchmark", "reference"),
    log:
        "results/{scene}/logs/benchmark.log",
    benchmark:
        "results/{scene}/benchmarks/benchmark.tsv"
    shell:
        "graphdem benchmark-report --tables {input.tables} --packings {input.packings} --main {params.main} "
        "--reference {params.reference} --out {output.table} --plot {output.plot} "
        "--title '{wildcards.scene}: run time against error' > {log} 2>&1"
