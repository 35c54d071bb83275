# Stage import (public benchmarks): Solid-GN pickles -> H5MD sims and their split table.
# The pickles are read with an unpickler that admits numpy arrays and nothing else.
rule import_solidgn:
    input:
        metadata=solidgn_metadata,
        scale=kept_scale,
    output:
        splits="results/{bench}/import/splits.csv",
    params:
        source=solidgn_source,
        limits=solidgn_limits,
    log:
        "results/{bench}/logs/import.log",
    benchmark:
        "results/{bench}/timings/import.tsv"
    shell:
        "graphdem import-solidgn {params.source:q} results/{wildcards.bench}/import {params.limits:q} "
        "--no-progress > {log} 2>&1"
