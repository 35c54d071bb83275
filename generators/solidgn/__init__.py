"""Import of the Solid-GN landslide benchmarks (Slide-SameR, Slide-Small) into our H5MD layout."""
