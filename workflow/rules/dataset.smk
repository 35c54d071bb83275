# Stage dataset: split table and train-split normalisation statistics, plus a picture of one sim. A scene's
# split table is its sweep (files in sims/); a public benchmark's comes from the import (with paths).
rule dataset:
    input:
        table=dataset_table,
        sims=all_sims,
    output:
        splits="results/{name}/dataset/splits.csv",
        stats="results/{name}/dataset/stats.json",
        plot=report("results/{name}/plots/dataset_sample.png", caption="../report/dataset.rst",
                    category=report_category, subcategory="dataset",
                    labels={"figure": "dataset sample (first and last frame)", "scene": "{name}"}),
    params:
        name=scene_or_benchmark_option,
        radius=connectivity_radius,
    wildcard_constraints:
        name=SCENE_OR_BENCHMARK,      # a user-data set's dataset is rule dataset_user's (user_data.smk)
    log:
        "results/{name}/logs/dataset.log",
    benchmark:
        "results/{name}/timings/dataset.tsv"
    shell:
        "graphdem dataset {params.name:q} --table {input.table:q} --sims results/{wildcards.name}/sims "
        "--out-dir results/{wildcards.name}/dataset --connectivity-radius {params.radius:q} "
        "--plot {output.plot:q} > {log} 2>&1"
