"""Graph-DEM surrogate: datasets, graph building, model, training, rollout and metrics."""
