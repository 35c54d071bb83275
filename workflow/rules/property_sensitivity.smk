# Stage property sensitivity: the property-sensitivity test (article Fig. 14; docs/surrogate.md, Property
# sensitivity). Each test sim is rerun by the DEM at the low and the high value of one node property
# (evaluate.property_sensitivity), all else kept, in results/{scene}/property/<i>/; the model rolls out both reruns;
# property_sensitivity.csv compares the change of the soil's mean x at the last frame, DEM against Graph-DEM, beside
# the DEM's own chaos.
rule property_rollout:
    input:
        checkpoint="results/{scene}/model/best.pt",
        sim="results/{scene}/property/{value}/sims/{sim}.h5",
    output:
        "results/{scene}/property/{value}/rollouts/{sim}.h5",
    params:
        runtime=runtime_json,
        device=device_arg,
    threads: 1
    resources:
        gpus=job_gpus,
    log:
        "results/{scene}/logs/property/rollout_{value}_{sim}.log",
    benchmark:
        "results/{scene}/timings/property/rollout_{value}_{sim}.tsv"
    shell:
        "graphdem rollout --checkpoint {input.checkpoint:q} --data {input.sim:q} "
        "--out-dir results/{wildcards.scene}/property/{wildcards.value}/rollouts --threads {threads} "
        "--runtime-json {params.runtime:q} {params.device:q} > {log} 2>&1"


rule property_sensitivity:
    input:
        unpack(property_sensitivity_inputs),
        checkpoint="results/{scene}/model/best.pt",
    output:
        table=report("results/{scene}/property_sensitivity.csv", caption="../report/property_sensitivity.rst",
                     category=report_category, subcategory="property sensitivity",
                     labels={"figure": "property_sensitivity.csv (download)", "scene": "{scene}"}),
        plot=report("results/{scene}/plots/property_sensitivity.png", caption="../report/property_sensitivity.rst",
                    category=report_category, subcategory="property sensitivity",
                    labels={"figure": "property sensitivity (Fig. 14)", "scene": "{scene}"}),
    params:
        args=property_sensitivity_args,
        runtime=runtime_json,
    threads: 1
    log:
        "results/{scene}/logs/property_sensitivity.log",
    benchmark:
        "results/{scene}/timings/property_sensitivity.tsv"
    shell:
        "graphdem property-sensitivity --checkpoint {input.checkpoint:q} {params.args:q} "
        "--runtime-json {params.runtime:q} --out {output.table:q} --plot {output.plot:q} --title {wildcards.scene:q} "
        "> {log} 2>&1"
