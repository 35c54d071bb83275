"""Engine-agnostic scene definitions."""
