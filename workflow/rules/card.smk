# Stage card (public benchmarks): the benchmark card, results/<bench>/card.csv and card.md (docs/benchmarks.md,
# "Benchmark card"): Graph-DEM and constant velocity under every protocol K, over the models of the seeds stage
# (rollout MSE, the first and last predicted frame, the error in particle diameters, blow-ups, training cost,
# rollout time) and, with two or more seeds, their seed ensemble (rule evaluate_seed_ensemble), beside the
# article's Table 6 figures (the config's <bench>.article).
rule card:
    input:
        unpack(seed_ensemble_tables),
        metrics=seed_metrics,
        per_step=seed_per_step,
        histories=seed_histories,
        stats="results/{name}/dataset/stats.json",
    output:
        csv=report("results/{name}/card.csv", caption="../report/card.rst", category=report_category,
                   subcategory="evaluation", labels={"figure": "benchmark card (download)", "scene": "{name}"}),
        md="results/{name}/card.md",
    params:
        seeds=seed_list,
        ensemble=card_ensemble_args,
        article=article_json,
        machine=card_machine_args,
    wildcard_constraints:
        name="|".join(BENCHMARKS),
    log:
        "results/{name}/logs/card.log",
    benchmark:
        "results/{name}/timings/card.tsv"
    shell:
        "graphdem card --benchmark {wildcards.name} --seeds {params.seeds:q} --metrics {input.metrics:q} "
        "--steps {input.per_step:q} --histories {input.histories:q} --stats {input.stats:q} "
        "{params.ensemble:q} --article-json {params.article:q} {params.machine:q} --out {output.csv:q} "
        "--markdown {output.md:q} > {log} 2>&1"
