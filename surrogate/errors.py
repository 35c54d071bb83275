"""Errors of the surrogate stages, importable without torch (the CLI names them for every job)."""


class CheckpointError(ValueError):
    """A checkpoint is missing, unreadable, or does not match what it is used with."""


class TrainingDiverged(RuntimeError):
    """The loss became non-finite; the message names the step and the samples."""
