"""DEM scene generators: scene definitions, engine drivers, raw output to H5MD."""
