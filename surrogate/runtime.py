"""How a trained surrogate computes a rollout: switches that change the arithmetic, not the weights.

Every switch comes from a scene's ``runtime`` config section (docs/performance.md gives each
one's measured effect):

* ``split_edge_mlp`` (exact): the first layer of every edge MLP is evaluated per node and gathered
  (:class:`surrogate.model.updater.Updater`);
* ``prune_isolated`` (exact): particles that are not predicted (kinematic, or asleep) and have no
  edge to a predicted one are left out of the graph. With no edge between two such particles, they
  cannot influence any prediction, so dropping them changes nothing. The generator then decodes,
  and the updater integrates, the predicted particles only;
* ``skip_kinematic_pairs`` (exact for a model trained this way, as every model here is): no edge
  joins two kinematic particles. Off, such edges are built: more work, and a graph the model never
  saw in training (the performance stage times both). Pruning and sleeping rely on it;
* ``precision``: ``float32`` (training's), ``float64``, or ``bfloat16`` (autocast of the network on
  the model's device type, CPU or CUDA; positions are integrated in float32);
* ``sleep_speed`` (not exact; null turns it off): a moving particle whose every history velocity is
  below this speed (m per frame) and that has no awake particle within R sleeps: it keeps its
  position, gets no prediction, and has no edge to another sleeping or kinematic particle. It wakes
  as soon as an awake particle comes within R;
* ``keep_in_domain`` (exact wherever the DEM keeps its particles in the box, as every recorded sim
  does: a particle leaving it is a blow-up, :mod:`generators.blowup`): a predicted position outside
  the dataset's box ``[lower, upper]`` is put back on the box face it crossed, so the particle stops
  there like on a rigid, perfectly inelastic wall (its velocity normal to the face, a position
  difference, becomes zero). The model has boundary features but no hard boundary; without this a
  long rollout can drift out of the domain (docs/performance.md). The rollout counts the particles
  put back (``clamped_per_step``), so the correction is never hidden;
* ``compile`` (exact to float32 rounding): the simulator's forward pass (features, constructor,
  processor, generator; not the graph building) runs through ``torch.compile`` with dynamic shapes,
  since the node and edge counts change every step. On the CPU, inductor generates C++ kernels and
  needs a C++ compiler and the Python headers (the Makefile's apt step). The first call of every new
  input kind (dtype, with or without properties or decoded subsets) compiles, which takes seconds
  to a minute: it pays only over many rollouts in one process (``python -m evaluation.timing.rollout``
  measures both).
* ``contact_correction`` (not exact; null turns it off): ``{allowed_overlap, iterations}`` and
  optionally ``tolerance`` (0 when absent). After
  every predicted step (and after ``keep_in_domain``), a moving particle whose path from the frame
  before passed a kinematic particle is stopped where it met it, then pairs that overlap by more than
  ``allowed_overlap`` times the smaller radius are pushed apart along their centre line, in at most
  ``iterations`` Jacobi sweeps, ended early once no pair overlaps by more than ``allowed_overlap`` plus
  ``tolerance`` (:mod:`surrogate.correction` gives the rule). The next step's
  velocities are differences of the corrected positions. The rollout counts the particles it stopped
  and the pairs it corrected (``stopped_particle_steps``, ``corrected_pair_steps`` in the stability
  report), so the correction is never hidden.
"""

from __future__ import annotations

from dataclasses import MISSING, asdict, dataclass, fields

import torch

from surrogate import devices

PRECISIONS = ("float64", "float32", "bfloat16")


@dataclass(frozen=True)
class Runtime:
    split_edge_mlp: bool
    skip_kinematic_pairs: bool
    prune_isolated: bool
    precision: str
    sleep_speed: float | None
    keep_in_domain: bool
    compile: bool
    contact_correction: dict | None = None      # {allowed_overlap, iterations[, tolerance]}; None: off

    def __post_init__(self):
        if self.precision not in PRECISIONS:
            raise ValueError(f"runtime.precision = {self.precision!r}: allowed are {', '.join(PRECISIONS)}")
        if not self.skip_kinematic_pairs and (self.prune_isolated or self.sleep_speed is not None):
            raise ValueError("runtime.prune_isolated and runtime.sleep_speed need runtime.skip_kinematic_pairs = "
                             "true: they leave out particles that have no edge to a predicted one")
        if self.sleep_speed is not None and not self.sleep_speed > 0:
            raise ValueError(f"runtime.sleep_speed = {self.sleep_speed!r}: a positive speed (m per frame) or null")
        if self.contact_correction is not None:
            check_contact_correction(self.contact_correction)

    @classmethod
    def from_config(cls, cfg: dict) -> Runtime:
        allowed = set(cls.__dataclass_fields__)
        required = {f.name for f in fields(cls) if f.default is MISSING}
        unknown, missing = set(cfg) - allowed, required - set(cfg)
        if unknown or missing:
            raise ValueError(f"runtime config: unknown keys {sorted(unknown)}, missing keys {sorted(missing)}; "
                             f"the keys are {sorted(allowed)}")
        return cls(**cfg)

    def as_dict(self) -> dict:
        return asdict(self)

    @property
    def network_dtype(self) -> torch.dtype:
        return torch.float64 if self.precision == "float64" else torch.float32

    def autocast(self, device: torch.device | str = "cpu"):
        """Context for the network's forward pass on ``device`` (bfloat16 autocast of that device's type,
        cpu or cuda, or nothing)."""
        return devices.autocast(torch.device(device), self.precision)


CONTACT_CORRECTION_KEYS = ("allowed_overlap", "iterations")
CONTACT_CORRECTION_OPTIONAL = ("tolerance",)     # absent: 0, the sweeps end only when no pair is too deep


def check_contact_correction(cfg: dict) -> None:
    """Refuse a ``runtime.contact_correction`` that is not ``{allowed_overlap: >= 0, iterations: >= 1}``
    with an optional ``tolerance: >= 0``."""
    if (not isinstance(cfg, dict) or not set(CONTACT_CORRECTION_KEYS) <= set(cfg)
            or not set(cfg) <= set(CONTACT_CORRECTION_KEYS + CONTACT_CORRECTION_OPTIONAL)):
        raise ValueError(f"runtime.contact_correction = {cfg!r}: null or a mapping with exactly the keys "
                         f"{', '.join(CONTACT_CORRECTION_KEYS)} and optionally "
                         f"{', '.join(CONTACT_CORRECTION_OPTIONAL)}")
    overlap, iterations = cfg["allowed_overlap"], cfg["iterations"]
    if isinstance(overlap, bool) or not isinstance(overlap, int | float) or not overlap >= 0:
        raise ValueError(f"runtime.contact_correction.allowed_overlap = {overlap!r}: a fraction of the smaller "
                         f"radius, >= 0")
    if isinstance(iterations, bool) or not isinstance(iterations, int) or iterations < 1:
        raise ValueError(f"runtime.contact_correction.iterations = {iterations!r}: an integer >= 1")
    tolerance = cfg.get("tolerance", 0)
    if isinstance(tolerance, bool) or not isinstance(tolerance, int | float) or not tolerance >= 0:
        raise ValueError(f"runtime.contact_correction.tolerance = {tolerance!r}: a fraction of the smaller "
                         f"radius, >= 0")


def apply(simulator: torch.nn.Module, runtime: Runtime) -> torch.nn.Module:
    """Set the switches that live in the modules (edge MLP form, float64 weights, a compiled forward pass);
    returns it. Compiling is in place (``nn.Module.compile``: the weights and the state dict stay the same)."""
    for module in simulator.modules():
        if hasattr(module, "split_edge_mlp"):
            module.split_edge_mlp = runtime.split_edge_mlp
    simulator = simulator.to(runtime.network_dtype)
    if runtime.compile:
        compile_forward(simulator)
    return simulator


def compile_forward(simulator: torch.nn.Module) -> None:
    """Compile ``simulator``'s forward pass in place (``nn.Module.compile``: the weights and the state dict stay
    the same), with dynamic shapes: every step has other node and edge counts, and a static compile would
    recompile at each one. The rollout's ``compile`` switch and training's ``train.compile`` both use it."""
    simulator.compile(dynamic=True)
