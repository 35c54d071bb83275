# Stage convert: raw engine output (any scene, any engine; its run.json says which) -> one validated H5MD file.
rule convert:
    input:
        "results/{scene}/raw/{sim}",
    output:
        "results/{scene}/sims/{sim}.h5",
    log:
        "results/{scene}/logs/convert/{sim}.log",
    benchmark:
        "results/{scene}/benchmarks/convert/{sim}.tsv"
    shell:
        "graphdem convert --raw {input} --out {output} > {log} 2>&1"
