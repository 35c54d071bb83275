# Stage shear stress: the shear stress predicted, for every scene whose section has a shear_stress_readout (the shear
# test; docs/scenes/shear.md, "The predicted shear stress"). A pair-force readout (evaluation/shear_stress.py) is
# fitted to the train sims' DEM frames and their shear_stress observable, chosen on valid; shear_stress_check reads
# the test sims' stress with it from the DEM's frames, Graph-DEM's rollouts and constant velocity into
# shear_stress.csv, beside the DEM's observable and its first DEM ensemble member's (the chaos).
rule shear_stress_readout:
    input:
        splits="results/{name}/dataset/splits.csv",
        sims=all_sims,
    output:
        readout="results/{name}/shear_stress/readout.pt",
        history="results/{name}/shear_stress/history.csv",
    params:
        settings=shear_stress_readout_json,
    wildcard_constraints:
        name="|".join(SHEAR_STRESS_SCENES),
    threads: 1
    log:
        "results/{name}/logs/shear_stress_readout.log",
    benchmark:
        "results/{name}/timings/shear_stress_readout.tsv"
    shell:
        "graphdem shear-stress-readout --splits {input.splits:q} --settings-json {params.settings:q} "
        "--out {output.readout:q} --history {output.history:q} --threads {threads} --no-progress > {log} 2>&1"


rule shear_stress_check:
    input:
        readout="results/{name}/shear_stress/readout.pt",
        checkpoint="results/{name}/model/best.pt",
        sims=test_sims,
        rollouts=evaluated_rollouts,
        ensemble=first_member_sims,
    output:
        table=report("results/{name}/shear_stress.csv", caption="../report/shear_stress.rst",
                     category=report_category, subcategory="shear stress",
                     labels={"figure": "shear_stress.csv (download)", "scene": "{name}"}),
        plot=report("results/{name}/plots/shear_stress.png", caption="../report/shear_stress.rst",
                    category=report_category, subcategory="shear stress",
                    labels={"figure": "shear stress curves", "scene": "{name}"}),
    params:
        args=shear_stress_check_args,
        runtime=runtime_json,
    wildcard_constraints:
        name="|".join(SHEAR_STRESS_SCENES),
    threads: 1
    log:
        "results/{name}/logs/shear_stress_check.log",
    benchmark:
        "results/{name}/timings/shear_stress_check.tsv"
    shell:
        "graphdem shear-stress-check --readout {input.readout:q} --checkpoint {input.checkpoint:q} "
        "--sims {input.sims:q} {params.args:q} --runtime-json {params.runtime:q} --out {output.table:q} "
        "--plot {output.plot:q} "
        "--title {wildcards.name:q} > {log} 2>&1"
