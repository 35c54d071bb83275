# Stage physics: a scene's DEM data checked against published physics, where the scene has such a check
# (Scene.physics; e.g. the column collapse's runout law). Every sim of the sweep is used.
rule physics:
    input:
        sims=all_sims,
    output:
        table="results/{scene}/physics.csv",
        plot=report("results/{scene}/plots/physics.png", caption="../report/physics.rst",
                    category=report_category, subcategory="physics",
                    labels={"figure": "DEM against published physics", "scene": "{scene}"}),
    params:
        cfg=scene_config_json,
    log:
        "results/{scene}/logs/physics.log",
    benchmark:
        "results/{scene}/timings/physics.tsv"
    shell:
        "graphdem physics --scene {wildcards.scene} --data {input.sims:q} --out {output.table:q} --plot {output.plot:q} "
        "--config-json {params.cfg:q} > {log} 2>&1"
