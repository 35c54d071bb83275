# Stage convert: raw engine output (any scene, any engine; its run.json says which) -> one validated H5MD file.
rule convert:
    input:
        "results/{run}/raw/{sim}",
    output:
        "results/{run}/sims/{sim}.h5",
    log:
        "results/{run}/logs/convert/{sim}.log",
    benchmark:
        "results/{run}/timings/convert/{sim}.tsv"
    shell:
        "graphdem convert --raw {input:q} --out {output:q} > {log} 2>&1"
