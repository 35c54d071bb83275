"""Pictures of an evaluation: metrics over frames (like the article's Fig. 10) and an animation."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from evaluation.metrics import shown, units  # noqa: E402
from generators.atomic import atomic_path  # noqa: E402
from generators.plots import SPECIES_COLOURS, draw_discs, frame_axes, plain, plane_section  # noqa: E402,F401

STYLE = {"truth": dict(color="black", lw=2.0, label="DEM (truth)"),
         "graphdem": dict(color="#d43d2a", lw=1.6, label="Graph-DEM"),
         "constant_velocity": dict(color="#777777", lw=1.2, ls="--", label="constant velocity"),
         "dem_ensemble": dict(color="#2a6fd4", lw=1.2, ls=":",
                              label="DEM ensemble (members from the last given frame)"),
         "dem_ensemble_mean": dict(color="#2a6fd4", lw=1.0, ls="-.", label="DEM ensemble mean")}
OTHER_COLOURS = ("#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#bcbd22", "#17becf")    # methods of no style


def _styles(methods: list[str]) -> dict[str, dict]:
    """The line style of every method: :data:`STYLE`'s, else one of :data:`OTHER_COLOURS` (the same in every
    panel), labelled by the method's name."""
    others = [m for m in methods if m not in STYLE]
    return {**{m: STYLE[m] for m in methods if m in STYLE},
            **{m: dict(color=OTHER_COLOURS[i % len(OTHER_COLOURS)], lw=1.2, label=plain(m))
               for i, m in enumerate(others)}}


def metrics_over_frames(per_step: pd.DataFrame, path: Path, title: str, x: str = "time") -> Path:
    """:func:`metrics_figure` written to ``path`` (PNG, atomically)."""
    fig = metrics_figure(per_step, title, x)
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    return path


def metrics_figure(per_step: pd.DataFrame, title: str, x: str = "time"):
    """One panel per metric: mean over test sims of truth and of each prediction against ``x``:
    ``time`` (s) or ``tau`` (the predicted frame's number, for data whose times are nominal). The legend sits
    below the panels, outside every one of them, so it covers no curve, tick or label."""
    if x not in ("time", "tau"):
        raise ValueError(f"x must be 'time' or 'tau', got {x!r}")
    mean = per_step[per_step["sim"] == "all"]
    several = "history" in mean.columns and mean["history"].nunique() > 1      # one panel per protocol and metric
    if several:
        mean = mean.assign(metric=[f"K = {k}: {m}" for k, m in zip(mean["history"], mean["metric"], strict=True)])
    metrics = list(dict.fromkeys(mean["metric"]))
    scene = str(mean["scene"].iloc[0]) if "scene" in mean.columns and len(mean) else None
    unit = units(scene)
    styles = _styles(list(dict.fromkeys(mean["method"])))
    cols = min(3, len(metrics))
    rows = int(np.ceil(len(metrics) / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(max(4.6 * cols, 6.0), 3.2 * rows + 0.8), squeeze=False,
                             layout="constrained")
    for ax, metric in zip(axes.flat, metrics, strict=False):
        part = mean[mean["metric"] == metric]
        first = part[part["method"] == part["method"].iloc[0]]
        if first["truth"].notna().any():
            ax.plot(first[x], first["truth"], **STYLE["truth"])
        for method, group in part.groupby("method", sort=False):
            ax.plot(group[x], group["prediction"], **styles[method])
        ax.set_title(plain(metric))
        ax.set_xlabel("time (s)" if x == "time" else "predicted frame")
        ax.set_ylabel(plain(shown(unit.get(metric.split(": ")[-1], ""))))
        ax.grid(alpha=0.3)
    for ax in list(axes.flat)[len(metrics):]:
        ax.set_visible(False)
    drawn = (["truth"] if mean["truth"].notna().any() else []) + list(styles)
    handles = [plt.Line2D([], [], **(STYLE | styles)[k]) for k in drawn]
    fig.legend(handles=handles, loc="outside lower center", ncol=min(len(handles), 3 if cols >= 3 else 2),
               fontsize=9, frameon=False)
    fig.suptitle(plain(title))
    return fig


def animation(path: Path, truth: np.ndarray, prediction: np.ndarray, radius: np.ndarray, species: np.ndarray,
              time: np.ndarray, lower: np.ndarray, upper: np.ndarray, history: int, title: str,
              labels: dict[int, str] | None = None, fps: int = 4, dpi: int = 70) -> Path:
    """GIF (Pillow, no external binary) of a 2D sim, or of a plane section of a 3D one
    (:func:`plane_section`; ``radius`` then a pair of [T, N] arrays, truth's and prediction's): DEM truth
    and Graph-DEM side by side, one GIF frame per frame of the sim.

    The axes, labels, legend and title are laid out and drawn once; each frame restores that picture and draws
    only what changes on it (the discs and the two panel titles), so a frame costs its particles, not a redraw of
    the figure. Non-finite positions (a blown-up rollout, a sphere the section misses) are not drawn."""
    from PIL import Image

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.6), dpi=dpi, sharey=True, constrained_layout=True)
    labels = labels or {}
    species = np.asarray(species)
    handles = [plt.Line2D([], [], marker="o", ls="", color=c, label=plain(labels.get(k, f"species {k}")))
               for k, c in SPECIES_COLOURS.items() if k in set(species.tolist())]
    radii = radius if isinstance(radius, tuple) else (radius, radius)
    panels = ((axes[0], truth, "DEM (truth)", radii[0]), (axes[1], prediction, "Graph-DEM", radii[1]))
    for ax, *_ in panels:
        frame_axes(ax, lower, upper)
        ax.set_title(" ", fontsize=9)
        ax.title.set_animated(True)              # drawn per frame, not into the background
    axes[0].set_ylabel("y (m)")
    axes[1].legend(handles=handles, loc="upper right", fontsize=7)
    fig.suptitle(plain(title))
    fig.canvas.draw()                            # lays the figure out once: every frame has the same axes
    fig.set_layout_engine("none")
    canvas = fig.canvas
    background = canvas.copy_from_bbox(fig.bbox)
    images = []
    for frame in range(len(truth)):
        canvas.restore_region(background)
        stage = "history (data)" if frame < history else f"predicted step {frame - history + 1}"
        for ax, pos, name, rad in panels:
            finite = np.isfinite(pos[frame]).all(axis=1)
            rad = np.asarray(rad)[frame] if np.ndim(rad) == 2 else np.asarray(rad)
            draw_discs(ax, pos[frame][finite], rad[finite], species[finite])
            discs = ax.collections[-1]
            ax.draw_artist(discs)
            discs.remove()
            ax.title.set_text(f"{name}: t = {time[frame]:.4g} s, {stage}")
            ax.draw_artist(ax.title)
        images.append(Image.fromarray(np.asarray(canvas.buffer_rgba())[..., :3].copy()))
    plt.close(fig)
    path = Path(path)
    with atomic_path(path) as tmp:
        images[0].save(tmp, format="GIF", save_all=True, append_images=images[1:], duration=int(1000 / fps),
                       loop=0)
    return path


# Where a point's number may go, in points from the point, tried in turn: the first that overlaps no marker and no
# number placed before it (right above, right below, left above, left below, then further out).
NUMBER_OFFSETS = tuple((side * dx, dy) for dx, dy in ((5, 2), (5, -10), (5, 11), (5, -19), (12, 20), (12, -28))
                       for side in (1, -1))
NUMBER_SIZE = 7                 # font size of the points' numbers and of the key


def _boxes_overlap(a: tuple[float, ...], b: tuple[float, ...]) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def number_points(fig, ax, xs, ys, marker_points: float = 7.0) -> list[tuple[float, float, float, float]]:
    """Write 1, 2, ... beside the points (``xs``, ``ys`` in data coordinates) of a laid-out axes, each at the first
    of :data:`NUMBER_OFFSETS` where it overlaps no marker (``marker_points`` wide) and no earlier number; returns
    the numbers' boxes (points, display origin)."""
    fig.canvas.draw()                                            # the layout that data -> display depends on
    scale = 72.0 / fig.dpi
    anchors = [tuple(scale * v for v in ax.transData.transform((x, y))) for x, y in zip(xs, ys, strict=True)]
    half = marker_points / 2
    taken = [(px - half, py - half, px + half, py + half) for px, py in anchors]
    placed = []
    for n, (px, py) in enumerate(anchors, 1):
        width, height = 0.62 * NUMBER_SIZE * len(str(n)), NUMBER_SIZE
        boxes = [(px + dx - (width if dx < 0 else 0), py + dy, px + dx + (0 if dx < 0 else width), py + dy + height)
                 for dx, dy in NUMBER_OFFSETS]
        choice = next((i for i, box in enumerate(boxes) if not any(_boxes_overlap(box, t) for t in taken)), 0)
        dx, dy = NUMBER_OFFSETS[choice]
        ax.annotate(str(n), (xs[n - 1], ys[n - 1]), textcoords="offset points", xytext=(dx, dy),
                    ha="right" if dx < 0 else "left", va="bottom", fontsize=NUMBER_SIZE)
        taken.append(boxes[choice])
        placed.append(boxes[choice])
    return placed


def pareto(table: pd.DataFrame, path: Path, title: str) -> Path:
    """:func:`pareto_figure` written to ``path`` (PNG, atomically)."""
    fig = pareto_figure(table, title)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=130)
    plt.close(fig)
    return Path(path)


def pareto_figure(table: pd.DataFrame, title: str):
    """Time per rollout (log) against rollout MSE for every scored contender, Pareto front joined; each point is
    numbered (the DEM's first, each kind from fast to slow; placed clear of the other points and numbers) and
    named by its number in the key beside the axes.

    The DEM reference has MSE 0 by definition: it sits on the x axis of a symlog error scale."""
    scored = table[table["mse"].notna() & table["seconds_per_rollout"].notna()]
    order = scored.assign(surrogate=scored["kind"] != "dem")
    scored = order.sort_values(["surrogate", "seconds_per_rollout"], kind="stable")
    fig, ax = plt.subplots(figsize=(9.0, 5.0), layout="constrained")
    markers = {"dem": dict(marker="s", color="#1f5fa8"), "surrogate": dict(marker="o", color="#d43d2a")}
    names = {"dem": "DEM", "surrogate": "Graph-DEM"}
    for kind, part in scored.groupby("kind", sort=False):
        ax.scatter(part["seconds_per_rollout"], part["mse"], s=42, label=names[kind], zorder=3, clip_on=False,
                   **markers[kind])
    front = scored[scored["on_pareto_front"].astype(bool)].sort_values("seconds_per_rollout")
    ax.step(front["seconds_per_rollout"], front["mse"], where="post", color="black", lw=1.0, alpha=0.7,
            label="Pareto front", zorder=2)
    ax.set_xscale("log")
    positive = scored.loc[scored["mse"] > 0, "mse"]
    ax.set_yscale("symlog", linthresh=0.1 * float(positive.min()) if len(positive) else 1.0)
    ax.set_ylim(bottom=0.0, top=float(scored["mse"].max()) * 8 if len(positive) else None)
    ax.set_xlabel("wall time per rollout (s, log)")
    ax.set_ylabel("rollout MSE against the DEM data (m$^2$)")
    ax.set_title(plain(title), fontsize=10)
    ax.grid(alpha=0.3, which="both")
    handles, _ = ax.get_legend_handles_labels()
    key = [plt.Line2D([], [], ls="", ms=4, label=plain(f"{n}  {row.contender}"), **markers[row.kind])
           for n, row in enumerate(scored.itertuples(), 1)]
    fig.legend(handles=handles + key, loc="outside right upper", fontsize=NUMBER_SIZE, frameon=False,
               ncol=1 if len(key) <= 30 else 2)
    number_points(fig, ax, scored["seconds_per_rollout"].to_numpy(float), scored["mse"].to_numpy(float))
    return fig


def _finish(fig, ax, path: Path, title: str, legend_size: int) -> Path:
    """Title, log grid and legend of a one-panel performance plot; written atomically to ``path`` and closed."""
    ax.set_title(plain(title), fontsize=10)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=legend_size)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=130)
    plt.close(fig)
    return Path(path)


def speedup_substeps(table: pd.DataFrame, main: str, path: Path, title: str) -> Path:
    """The surrogate's speed-up over the DEM against the DEM sub-steps per frame (log-log): one line per
    stable DEM contender's cost per step, its own sub-steps per frame marked; the matched DEM (as
    accurate on every measure) drawn bold. Above 1 the surrogate is faster."""
    from evaluation.performance import speedup_curve
    row = table.loc[table["contender"] == main].iloc[0]
    dem = table[(table["kind"] == "dem") & table["stable"].astype(bool) & table["seconds_per_dem_step"].notna()]
    top = max(10.0, float(dem["dem_steps_per_frame"].max()) * 10) if len(dem) else 1e4
    substeps = np.logspace(0, np.log10(top), 60)
    curve = speedup_curve(table, main, substeps)
    fig, ax = plt.subplots(figsize=(7.5, 4.8), constrained_layout=True)
    colours = plt.cm.viridis(np.linspace(0, 0.9, max(len(dem), 1)))
    for colour, (_, d) in zip(colours, dem.iterrows(), strict=False):
        part = curve[curve["contender"] == d["contender"]]
        bold = d["contender"] == row.get("matched_dem")
        ax.plot(part["substeps_per_frame"], part["speedup"], color=colour, lw=2.4 if bold else 1.0,
                label=plain(f"{d['contender']} ({d['cores']:.0f} core{'s' if d['cores'] > 1 else ''})"
                            + (", as accurate" if bold else "")))
        actual = d["dem_steps_per_frame"] * d["seconds_per_dem_step"] / row["seconds_per_frame"]
        ax.scatter([d["dem_steps_per_frame"]], [actual], color=colour, s=30, zorder=3)
    ax.axhline(1.0, color="black", lw=0.8)
    ax.axhline(10.0, color="grey", lw=0.8, ls="--")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("DEM sub-steps per recorded frame (log; dots: each contender's own)")
    ax.set_ylabel(plain(f"speed-up of {main} over the DEM (log)"))
    return _finish(fig, ax, path, title, legend_size=7)


def performance_map(sims: pd.DataFrame, path: Path, title: str) -> Path:
    """Where the surrogate pays (evaluation/performance_map.py): per test sim (a dot) and DEM comparison (a colour),
    the surrogate's speed-up against the DEM sub-steps per frame that DEM contender took on that sim (log-log); the
    line speed-up = n / n* through the comparison's median break-even n*, and speed-up 1 (break-even) and 10."""
    fig, ax = plt.subplots(figsize=(7.5, 4.8), constrained_layout=True)
    colours = dict(zip(("as accurate", "as accurate by MSE", "reference"), ("#d43d2a", "#2a6fd4", "#777777"),
                       strict=True))
    for match, part in sims.groupby("match", sort=False):
        colour = colours.get(match, "#2ca02c")
        n_star = float(part["break_even_steps"].median())
        label = plain(f"{match}: {part['dem_contender'].iloc[0]} (break-even {n_star:.3g} sub-steps per frame)")
        ax.scatter(part["dem_steps_per_frame"], part["speedup"], color=colour, s=30, zorder=3, label=label)
        n = np.logspace(np.log10(max(1.0, part["dem_steps_per_frame"].min() / 3)),
                        np.log10(part["dem_steps_per_frame"].max() * 3), 30)
        ax.plot(n, n / n_star, color=colour, lw=0.9)
    ax.axhline(1.0, color="black", lw=0.8)
    ax.axhline(10.0, color="grey", lw=0.8, ls="--")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("DEM sub-steps per recorded frame on the sim (log)")
    ax.set_ylabel(plain(f"speed-up of {sims['surrogate'].iloc[0]} on the sim (log)" if len(sims) else "speed-up"))
    return _finish(fig, ax, path, title, legend_size=7)


def stability(frames: pd.DataFrame, path: Path, title: str) -> Path:
    """Kinetic energy (log) and the overlap distribution (max and 99th percentile of overlap / radius)
    per frame of each long rollout, frames outside the physical envelope marked."""
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7.5, 6.0), sharex=True, constrained_layout=True)
    quantile = [c for c in frames.columns if c.startswith("p") and c.endswith("_overlap")]
    for (sim, length), part in frames.groupby(["sim", "length"]):
        label = plain(f"{sim}, {length}x window")
        line, = top.plot(part["frame"], part["kinetic_energy"], lw=1.0, label=label)
        bad = part[~part["in_envelope"].astype(bool)]
        top.scatter(bad["frame"], bad["kinetic_energy"], color=line.get_color(), marker="x", s=14)
        bottom.plot(part["frame"], part["max_overlap"], color=line.get_color(), lw=1.0)
        if quantile:
            bottom.plot(part["frame"], part[quantile[0]], color=line.get_color(), lw=1.0, ls=":")
    top.set_yscale("log")
    top.set_ylabel("kinetic energy of the moving particles")
    bottom.set_ylabel("overlap / smaller radius\n(solid: max, dotted: 99th percentile)")
    bottom.set_xlabel("frame")
    top.set_title(plain(f"{title} (x: outside the physical envelope)"), fontsize=10)
    top.legend(fontsize=7)
    for ax in (top, bottom):
        ax.grid(alpha=0.3)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=130)
    plt.close(fig)
    return Path(path)


def property_sensitivity(pairs: list, table: pd.DataFrame, path: Path, title: str) -> Path:
    """Article Fig. 14 and its measure: the first sim's moving particles at the last frame (x against the
    vertical axis) with the low property value in red and the high one in grey on top, truth and Graph-DEM
    side by side, each run's mean x marked; then the Delta of mean x (high - low) per sim, DEM against
    Graph-DEM and constant velocity, with the DEM's own chaos as error bars."""
    pair = pairs[0]
    moving = ~np.asarray(pair.truth_low.kinematic, bool)
    vertical = pair.truth_low.dim - 1
    fig, axes = plt.subplots(1, 3, figsize=(13.0, 4.0), constrained_layout=True)
    panels = (("DEM", pair.truth_low.position[-1], pair.truth_high.position[-1]),
              ("Graph-DEM", pair.predicted_low[-1], pair.predicted_high[-1]))
    for ax, (who, low, high) in zip(axes[:2], panels, strict=True):
        for frame, colour, value in ((low, "tab:red", pair.low), (high, "0.6", pair.high)):
            ax.scatter(frame[moving, 0], frame[moving, vertical], s=4, color=colour, label=f"{value:.3g}")
            ax.axvline(float(np.mean(frame[moving, 0])), color=colour, ls="--", lw=1.0)
        ax.set_title(plain(f"{who}, {pair.sim}, last frame (dashed: mean x)"), fontsize=9)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("z (m)" if vertical == 2 else "y (m)")
        ax.set_aspect("equal")
        ax.legend(fontsize=7, title=plain(table["property"].iloc[0]), title_fontsize=7)
    rows = table[table["sim"] != "all"]
    at = np.arange(len(rows))
    bars = axes[2]
    bars.bar(at - 0.27, rows["dem_delta"] * 1e6, width=0.27, label="DEM")
    bars.bar(at, rows["graphdem_delta"] * 1e6, width=0.27, label="Graph-DEM")
    bars.bar(at + 0.27, rows["cv_delta"] * 1e6, width=0.27, color="0.7", label="constant velocity")
    if rows["chaos_delta"].notna().any():
        chaos = rows["chaos_delta"].to_numpy() * 1e6
        bars.errorbar(at - 0.27, rows["dem_delta"] * 1e6, yerr=chaos, fmt="none", color="k", capsize=3,
                      label="DEM chaos (+-)")
    bars.axhline(0.0, color="k", lw=0.6)
    bars.set_xticks(at, [plain(s) for s in rows["sim"]], rotation=30, fontsize=7)
    bars.set_ylabel("Delta mean x, high - low (um)")
    bars.set_title("property sensitivity per test sim", fontsize=9)
    bars.legend(fontsize=7)
    fig.suptitle(plain(title), fontsize=10)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=130)
    plt.close(fig)
    return Path(path)


def stress_curves(curves: list, table: pd.DataFrame, history: int, path: Path, title: str) -> Path:
    """The shear stress against the shear displacement, one panel per test sim: the DEM's observable, the readout
    on the DEM's frames, on Graph-DEM's rollout and on constant velocity, the DEM ensemble's observable and the
    Coulomb floor (the train sims' mean stress ratio); the given frames shaded (evaluation.shear_stress_check). Each
    panel's y range is set by the DEM's curves (its observable, the readout on its frames, the ensemble's) up to
    twice their peak: a prediction far off leaves the panel, and the title gives its peak error and the floor's."""
    styles = {"readout": ("readout on DEM frames", "0.45", "--"), "graphdem": ("Graph-DEM", "tab:blue", "-"),
              "cv": ("constant velocity", "tab:orange", "-"), "ensemble": ("DEM ensemble", "tab:green", ":"),
              "coulomb": ("Coulomb, train sims' mean", "tab:purple", "-.")}
    fig, axes = plt.subplots(1, len(curves), figsize=(3.6 * len(curves), 3.4), squeeze=False)
    for ax, curve in zip(axes[0], curves, strict=True):
        mm = 1e3 * curve.displacement
        ax.axvspan(mm[0], mm[history - 1], color="0.9", lw=0)
        ax.plot(mm, 1e-3 * curve.dem, color="black", lw=2, label="DEM")
        for name, (label, colour, line) in styles.items():
            if np.isfinite(curve.predicted[name]).any():
                ax.plot(mm, 1e-3 * curve.predicted[name], color=colour, ls=line, label=label)
        dem_side = np.concatenate([curve.dem, curve.predicted["readout"], curve.predicted["ensemble"]])
        dem_side = 1e-3 * dem_side[np.isfinite(dem_side)]
        top = 2.0 * max(float(dem_side.max()), 0.0)
        if top > 0:
            ax.set_ylim(min(0.0, float(dem_side.min())) - 0.05 * top, top)
        row = table[table["sim"] == curve.sim].iloc[0]
        ax.set_title(plain(f"{curve.sim}: {row['normal_stress'] / 1e3:.3g} kPa, E {row['young']:.2g} Pa\n"
                           f"peak error: Graph-DEM {100 * row['graphdem_error']:+.0f} %, "
                           f"Coulomb {100 * row['coulomb_error']:+.0f} %"), fontsize=8)
        ax.set_xlabel("shear displacement (mm)")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("shear stress (kPa)")
    axes[0][0].legend(fontsize=7)
    fig.suptitle(plain(title), fontsize=9)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=130)
    plt.close(fig)
    return Path(path)
