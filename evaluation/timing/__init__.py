"""Timings run by hand, each ``python -m evaluation.timing.<name>``: the cost per rollout frame lever by lever
(rollout), the radius-graph methods (graph), the largest graph a training step fits (memory) and the contact
correction's pair search (correction); docs/performance.md, docs/surrogate.md and docs/scaling.md give their
figures."""
