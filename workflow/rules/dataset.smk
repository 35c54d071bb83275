# Stage dataset: split table and train-split normalisation statistics, plus a picture of one sim.
rule dataset:
    input:
        sweep="results/{scene}/sweep.csv",
        sims=all_sims,
    output:
        splits="results/{scene}/dataset/splits.csv",
        stats="results/{scene}/dataset/stats.json",
        plot=report("results/{scene}/plots/dataset_sample.png", caption="../report/dataset.rst", category="dataset"),
    params:
        radius=connectivity_radius,
    log:
        "results/{scene}/logs/dataset.log",
    benchmark:
        "results/{scene}/benchmarks/dataset.tsv"
    shell:
        "graphdem dataset --scene {wildcards.scene} --sweep {input.sweep} "
        "--sims results/{wildcards.scene}/sims --out-dir results/{wildcards.scene}/dataset "
        "--connectivity-radius {params.radius} --plot {output.plot} > {log} 2>&1"


# The same stage for a public benchmark: the split table comes from the import.
rule dataset_benchmark:
    input:
        splits="results/{bench}/import/splits.csv",
    output:
        splits="results/{bench}/dataset/splits.csv",
        stats="results/{bench}/dataset/stats.json",
        plot=report("results/{bench}/plots/dataset_sample.png", caption="../report/dataset.rst", category="dataset"),
    params:
        radius=connectivity_radius,
    log:
        "results/{bench}/logs/dataset.log",
    benchmark:
        "results/{bench}/benchmarks/dataset.tsv"
    shell:
        "graphdem dataset --scene {wildcards.bench} --splits {input.splits} "
        "--out-dir results/{wildcards.bench}/dataset --connectivity-radius {params.radius} "
        "--plot {output.plot} > {log} 2>&1"
