"""What measures a trained Graph-DEM surrogate: the evaluation against the DEM, the constant-velocity baseline
and the DEM ensemble (metrics, summaries, tables), the seeds and the benchmark card, the performance and
stability stages, the shear-stress readout and its check, the property sensitivity test, the timings and the
docs' generated tables. It imports ``surrogate`` and ``generators``; ``surrogate`` never imports it
(docs/architecture.md, "Packages")."""
