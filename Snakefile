# Graph-DEM pipeline: DEM parameter sweeps -> H5MD -> dataset -> train -> rollout -> evaluate.
#
#   snakemake -c2 results/slide/metrics.csv                        # the main job
#   snakemake -c2 results/slide/metrics.csv --config scale=ci      # tiny, for tests
#   snakemake -c2 results/slide/metrics.csv --config slide='{young: 5.0e9}'
#   snakemake -c2 --forcerun train results/slide/metrics.csv       # rerun one stage
#   snakemake -c2 results/slide/dataset/stats.json                 # stop after a stage
#   snakemake -c2 results/slide/benchmark.csv                      # run time against error
#   snakemake -c2 results/slide/stability.csv                      # stress tests (docs/performance.md)
#   snakemake -c2 results/slide_samer/metrics.csv --config solidgn_root=/path/to/solidgn   # Table 6
#
# The configuration is validated against workflow/schemas/config.schema.yaml before anything runs.

import os

from snakemake.utils import min_version

min_version("9.0")


configfile: os.path.join(workflow.basedir, "workflow", "config", "default.yaml")


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
include: "workflow/rules/benchmark.smk"


rule all:
    input:
        expand("results/{scene}/metrics.csv", scene=SCENES),
    default_target: True


# The public benchmarks need solidgn_root, so they are a target of their own, not part of `all`.
rule benchmarks:
    input:
        expand("results/{bench}/metrics.csv", bench=BENCHMARKS),
