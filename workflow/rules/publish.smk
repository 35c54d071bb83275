# Stage publish: a scene's trained model as a pretrained checkpoint with its model card (evaluation/publish.py);
# the package ships the default scale's in surrogate/pretrained/ (docs/pretrained.md).
rule publish:
    input:
        checkpoint="results/{scene}/model/best.pt",
        splits="results/{scene}/dataset/splits.csv",
        metrics="results/{scene}/metrics.csv",
    output:
        checkpoint="results/{scene}/pretrained/{scene}.pt",
        card="results/{scene}/pretrained/{scene}.md",
    params:
        runtime=runtime_json,
    log:
        "results/{scene}/logs/publish.log",
    benchmark:
        "results/{scene}/timings/publish.tsv"
    shell:
        "graphdem publish --scene {wildcards.scene} --checkpoint {input.checkpoint:q} --splits {input.splits:q} "
        "--metrics {input.metrics:q} --runtime-json {params.runtime:q} "
        "--out-dir results/{wildcards.scene}/pretrained > {log} 2>&1"
