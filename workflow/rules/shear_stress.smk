# Stage stress: a stress observable predicted, for every scene whose section has a stress_readout (the shear test;
# docs/scenes/shear.md, "The predicted shear stress"). A pair-force readout (evaluation/shear_stress.py) is fitted to the
# train sims' DEM frames and their shear_stress observable, chosen on valid; stress.csv reads the test sims' stress
# from the DEM's frames, Graph-DEM's rollouts and constant velocity with it, beside the DEM's observable and its
# first DEM ensemble member's (the chaos).
rule stress_readout:
    input:
        splits="results/{name}/dataset/splits.csv",
        sims=all_sims,
    output:
        readout="results/{name}/stress/readout.pt",
        history="results/{name}/stress/history.csv",
    params:
        settings=stress_readout_json,
    wildcard_constraints:
        name="|".join(STRESS_SCENES),
    threads: 1
    log:
        "results/{name}/logs/stress_readout.log",
    benchmark:
        "results/{name}/timings/stress_readout.tsv"
    shell:
        "graphdem stress-readout --splits {input.splits:q} --settings-json {params.settings:q} "
        "--out {output.readout:q} --history {output.history:q} --threads {threads} --no-progress > {log} 2>&1"


rule stress_test:
    input:
        readout="results/{name}/stress/readout.pt",
        checkpoint="results/{name}/model/best.pt",
        sims=test_sims,
        rollouts=evaluated_rollouts,
        ensemble=first_member_sims,
    output:
        table=report("results/{name}/stress.csv", caption="../report/stress.rst",
                     category=report_category, subcategory="stress",
                     labels={"figure": "stress.csv (download)", "scene": "{name}"}),
        plot=report("results/{name}/plots/stress.png", caption="../report/stress.rst",
                    category=report_category, subcategory="stress",
                    labels={"figure": "stress curves", "scene": "{name}"}),
    params:
        args=stress_test_args,
    wildcard_constraints:
        name="|".join(STRESS_SCENES),
    threads: 1
    log:
        "results/{name}/logs/stress_test.log",
    benchmark:
        "results/{name}/timings/stress_test.tsv"
    shell:
        "graphdem stress-test --readout {input.readout:q} --checkpoint {input.checkpoint:q} --sims {input.sims:q} "
        "{params.args:q} --out {output.table:q} --plot {output.plot:q} --title {wildcards.name:q} > {log} 2>&1"
