"""Pictures of 2D particle configurations (discs drawn to scale)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import EllipseCollection  # noqa: E402

from generators.atomic import atomic_path  # noqa: E402

SPECIES_COLOURS = {0: "#555555", 1: "#b5895a", 2: "#d43d2a", 3: "#3a6fb0"}


def plain(text: object) -> str:
    """``text`` as matplotlib draws it literally: every ``$`` escaped, so that text from data (a file name, a sim
    id, a species name, a title given on the command line) is never read as mathtext markup (``$\\alpha$_x``
    is drawn as typed, and an unbalanced or malformed one cannot make the plot fail)."""
    return str(text).replace("$", r"\$")


def draw_discs(ax, xy: np.ndarray, radius: np.ndarray, species: np.ndarray, alpha: float = 1.0) -> None:
    colours = [SPECIES_COLOURS.get(int(s), "#888888") for s in species]
    d = 2 * np.asarray(radius)
    ax.add_collection(EllipseCollection(d, d, np.zeros_like(d), units="xy", offsets=xy,
                                        offset_transform=ax.transData, facecolors=colours,
                                        edgecolors="none", alpha=alpha))


def plane_section(position: np.ndarray, radius: np.ndarray, height: float, axis: int = 2
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The cut of 3D spheres by the plane x_axis = ``height``: centres in the two other axes [T, N, 2]
    (NaN for a sphere the plane misses) and the radius of each cut circle [T, N]."""
    position = np.asarray(position, np.float64)
    dz = position[..., axis] - height
    with np.errstate(invalid="ignore"):
        r2 = np.asarray(radius, np.float64)[None, :] ** 2 - dz**2
        cut = r2 > 0
    others = [a for a in range(3) if a != axis]
    xy = np.where(cut[..., None], position[..., others], np.nan)
    return xy, np.sqrt(np.where(cut, r2, 0.0))


def frame_axes(ax, lower: np.ndarray, upper: np.ndarray) -> None:
    """Axes of a 2D particle picture: the domain, to scale, in metres."""
    ax.set_xlim(lower[0], upper[0])
    ax.set_ylim(lower[1], upper[1])
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")


def first_last(path: str | Path, position: np.ndarray, radius: np.ndarray, species: np.ndarray,
               time: np.ndarray, lower: np.ndarray, upper: np.ndarray, title: str,
               labels: dict[int, str] | None = None, ylabel: str = "y (m)") -> Path:
    """Side-by-side picture of a 2D trajectory's first and last frame (``radius`` [N], or [T, N] for a
    plane section of a 3D one, whose missed spheres are NaN in ``position``)."""
    fig, axes = plt.subplots(1, 2, figsize=(12, 5), sharey=True, constrained_layout=True)
    for ax, frame in zip(axes, (0, len(position) - 1), strict=True):
        shown = np.isfinite(position[frame]).all(axis=1)
        rad = np.asarray(radius)[frame] if np.ndim(radius) == 2 else np.asarray(radius)
        draw_discs(ax, position[frame][shown], rad[shown], np.asarray(species)[shown])
        frame_axes(ax, lower, upper)
        ax.set_title(f"frame {frame}, t = {time[frame]:.4g} s")
    axes[0].set_ylabel(ylabel)
    if labels:
        handles = [plt.Line2D([], [], marker="o", ls="", color=SPECIES_COLOURS.get(k, "#888"), label=plain(v))
                   for k, v in labels.items()]
        axes[1].legend(handles=handles, loc="upper right")
    fig.suptitle(plain(title))
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format=path.suffix.lstrip(".") or "png")
    plt.close(fig)
    return path
