# Stage export: a scene's test sims and their Graph-DEM rollouts as ParaView time series (docs/export.md).
# results/<scene>/vtk/<sim>/dem.pvd is the DEM sim, <sim>/graphdem.pvd the rollout with its per-particle
# error against it; each .pvd lists the .vtu frames in the folder of its name. A failed export stops the
# job (and Snakemake removes the folder). Not part of `all`:
#   snakemake -c2 results/<scene>/vtk
rule export:
    input:
        sims=export_sims,
        rollouts=export_rollouts,
    output:
        directory("results/{scene}/vtk"),
    params:
        ids=export_ids,
    threads: 1
    log:
        "results/{scene}/logs/export.log",
    benchmark:
        "results/{scene}/timings/export.tsv"
    shell:
        "for sim in {params.ids:q}; do "
        "graphdem export \"results/{wildcards.scene}/sims/$sim.h5\" --out {output:q}\"/$sim/dem.pvd\" && "
        "graphdem export \"results/{wildcards.scene}/rollouts/$sim.h5\" --truth \"results/{wildcards.scene}/sims/$sim.h5\" "
        "--out {output:q}\"/$sim/graphdem.pvd\" || exit 1; done > {log:q} 2>&1"
