# Graph-DEM pipeline: DEM parameter sweeps -> H5MD -> dataset (-> surrogate, in later stages).
#
#   snakemake -c2 results/slide/dataset/stats.json                 # the slide dataset
#   snakemake -c2 results/slide/dataset/stats.json --config scale=ci
#   snakemake -c2 results/slide/dataset/stats.json --config slide='{young: 5.0e9}'
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
include: "workflow/rules/dataset.smk"


rule all:
    input:
        expand("results/{scene}/dataset/stats.json", scene=SCENES),
    default_target: True
