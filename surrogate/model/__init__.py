"""Graph-DEM layers (article section 4): constructor, processor of updaters, generator."""
