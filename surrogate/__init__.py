"""Graph-DEM surrogate: datasets, graph building, model, training and rollout. What measures it is the package
``evaluation``, which imports this one and never the other way round (docs/architecture.md, "Packages")."""
