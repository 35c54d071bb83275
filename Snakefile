# Graph-DEM pipeline: DEM parameter sweeps -> H5MD -> dataset -> train -> rollout -> evaluate.
#
#   snakemake -c2 results/slide/metrics.csv                        # the main job
#   snakemake -c2 results/slide/metrics.csv --config scale=ci      # tiny, for tests
#   snakemake -c2 results/slide/metrics.csv --config slide='{young: 5.0e9}'
#   snakemake -c2 --forcerun train results/slide/metrics.csv       # rerun one stage
#   snakemake -c2 results/slide/dataset/stats.json                 # stop after a stage
#   snakemake -c2 results/collapse/metrics.csv                     # the granular column collapse
#   snakemake -c2 results/slide/performance.csv                    # run time against error
#   snakemake -c2 results/slide/stability.csv                      # stress tests (docs/performance.md)
#   snakemake -c2 results/crosscheck.csv                           # LAMMPS against YADE (docs/crosscheck.md)
#   snakemake -c2 results/crosscheck/slide_transfer.csv            # the model scored on the other engine
#   snakemake -c2 results/slide_samer/metrics.csv --config solidgn_root=/path/to/solidgn   # Table 6
#
# Defaults are package data: generators/defaults/default.yaml and, per scene, generators/scenes/<scene>.yaml
# (with its scale presets). --config and --configfile override them; the result is validated against
# generators/defaults/schema.yaml and the scenes' schema fragments before anything runs.

from snakemake.utils import min_version

min_version("9.0")


include: "workflow/rules/common.smk"
include: "workflow/rules/sweep.smk"
include: "workflow/rules/prepare.smk"
include: "workflow/rules/simulate.smk"
include: "workflow/rules/convert.smk"
include: "workflow/rules/import.smk"
include: "workflow/rules/dataset.smk"
include: "workflow/rules/train.smk"
include: "workflow/rules/rollout.smk"
include: "workflow/rules/evaluate.smk"
include: "workflow/rules/stability.smk"
include: "workflow/rules/performance.smk"
include: "workflow/rules/physics.smk"
include: "workflow/rules/crosscheck.smk"


rule all:
    input:
        expand("results/{scene}/metrics.csv", scene=SCENES),
    default_target: True


# The public benchmarks need solidgn_root, so they are a target of their own, not part of `all`.
rule benchmarks:
    input:
        expand("results/{bench}/metrics.csv", bench=BENCHMARKS),
