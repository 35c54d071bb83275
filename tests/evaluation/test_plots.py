"""The rollout animation: one GIF frame per sim frame, each panel drawing its own positions."""

import numpy as np
from PIL import Image

from evaluation import plots

BLUE = np.array([0x3A, 0x6F, 0xB0])          # species 3 in generators.plots.SPECIES_COLOURS


def _blue_columns(frame: Image.Image) -> tuple[float, float]:
    """Mean pixel column of the blue disc in the left and in the right half of a GIF frame (NaN: none); rows
    about the disc's height only (the legend's blue marker sits at the top right)."""
    rgb = np.asarray(frame.convert("RGB"), float)
    rows = rgb.shape[0]
    rgb = rgb[int(0.3 * rows):int(0.85 * rows)]
    blue = np.linalg.norm(rgb - BLUE, axis=-1) < 30
    half = rgb.shape[1] // 2
    cols = np.nonzero(blue)[1]
    left, right = cols[cols < half], cols[cols >= half]
    return (left.mean() if len(left) else np.nan), (right.mean() if len(right) else np.nan)


def test_each_frame_shows_each_panels_positions_and_skips_non_finite_ones(tmp_path):
    t = 4
    truth = np.zeros((t, 2, 2))
    truth[:, 0] = np.c_[np.linspace(2.0, 8.0, t), np.full(t, 5.0)]     # the disc moves right
    truth[:, 1] = [5.0, 0.4]                                           # a still grey one on the floor
    prediction = truth.copy()
    prediction[:, 0, 0] = 2.0                                          # the prediction holds it still ...
    prediction[3, 0] = np.nan                                          # ... until it blows up
    path = plots.animation(tmp_path / "a.gif", truth, prediction, np.array([0.6, 0.4]), np.array([3, 0]),
                           np.arange(t) * 0.1, np.zeros(2), np.full(2, 10.0), history=1, title="moving disc")
    gif = Image.open(path)
    assert gif.n_frames == t and gif.info["duration"] == 250
    columns = []
    for k in range(t):
        gif.seek(k)
        columns.append(_blue_columns(gif))
    left, right = np.array(columns).T
    assert np.all(np.diff(left) > 20)                  # truth: 2 m per frame, at least 20 pixels each
    assert np.ptp(right[:3]) < 1.0 and abs(right[0] - left[0] - gif.width / 2) < 25   # held at x = 2
    assert np.isnan(right[3])                          # the non-finite disc is not drawn


def _per_step(metrics: list[str]):
    import pandas as pd
    rows = [{"sim": "all", "scene": "slide", "method": method, "metric": metric, "tau": tau, "time": 0.2 * tau,
             "truth": np.nan if metric == "rollout MSE" else 2.0 + np.sin(tau), "prediction": 2.0 + 0.1 * tau}
            for metric in metrics for method in ("graphdem", "constant_velocity", "dem_ensemble", "dem_ensemble_mean")
            for tau in range(1, 8)]
    return pd.DataFrame(rows)


def _overlap(a, b) -> bool:
    return a.x0 < b.x1 and b.x0 < a.x1 and a.y0 < b.y1 and b.y0 < a.y1


def test_the_metrics_legend_covers_no_panel_and_names_every_method():
    """A full grid (12 panels: the lower right one in use) and one panel: the legend lies below every panel, its
    curves, ticks and labels, and names each method drawn, the DEM ensemble mean too."""
    import matplotlib.pyplot as plt
    slide = ["rollout MSE", "Slide Num", "Max Ht", "Mean Ht", "Tongue Dis", "Dis", "Dis mean", "Max overlap",
             "P99 overlap", "Outside box", "Through wall", "Kinetic energy"]
    for metrics in (slide, slide[:1]):
        fig = plots.metrics_figure(_per_step(metrics), "slide: mean over 6 test sims")
        renderer = fig.canvas.get_renderer()
        fig.canvas.draw()
        legend = fig.legends[0].get_window_extent(renderer)
        panels = [ax for ax in fig.axes if ax.get_visible()]
        assert len(panels) == len(metrics)
        assert not [ax.get_title() for ax in panels if _overlap(legend, ax.get_tightbbox(renderer))]
        assert legend.y1 <= min(ax.get_tightbbox(renderer).y0 for ax in panels)
        labels = [t.get_text() for t in fig.legends[0].get_texts()]
        assert labels[-1] == "DEM ensemble mean" and "Graph-DEM" in labels
        assert panels[0].get_ylabel() == "m²"
        plt.close(fig)


def test_the_pareto_points_are_numbered_clear_of_each_other_and_named_in_a_key_beside_the_axes():
    """Twelve contenders, several at nearly one point: every number stays clear of every other number and every
    marker, and the key outside the axes names each by its number (the DEM's first, each kind fast to slow)."""
    import matplotlib.pyplot as plt
    import pandas as pd
    dem = {"reference": (40.0, 0.0), "dt_5pct": (38.0, 0.002), "dt_10pct": (20.0, 0.02), "dt_50pct": (5.0, 1.9),
           "dt_50pct_2cores": (5.0, 1.9), "stiffness_div10": (13.0, 0.6)}
    surrogate = {"graphdem": (1.2, 0.31), "compiled": (0.9, 0.31), "bfloat16": (0.9, 0.33), "batch_4": (0.5, 0.31),
                 "no_correction": (1.0, 0.35), "float64": (1.9, 0.31), "article_size": (6.0, np.nan)}
    table = pd.DataFrame([{"contender": name, "kind": kind, "seconds_per_rollout": t, "mse": e,
                           "on_pareto_front": name in ("reference", "dt_10pct", "batch_4")}
                          for kind, group in (("dem", dem), ("surrogate", surrogate))
                          for name, (t, e) in group.items()])
    fig = plots.pareto_figure(table, "slide: run time against error")
    renderer = fig.canvas.get_renderer()
    fig.canvas.draw()
    ax = fig.axes[0]
    numbers = [t for t in ax.texts if t.get_text().isdigit()]
    assert sorted(int(t.get_text()) for t in numbers) == list(range(1, 13))        # article_size: timed, not scored
    boxes = [t.get_window_extent(renderer) for t in numbers]
    assert not [(i, j) for i in range(len(boxes)) for j in range(i) if _overlap(boxes[i], boxes[j])]
    markers = [c.get_offsets() for c in ax.collections]
    centres = ax.transData.transform(np.concatenate(markers))
    half = 3.2 * fig.dpi / 72.0                                    # the markers' half width (s = 42: 6.5 points)
    hit = [(t.get_text(), c) for t, b in zip(numbers, boxes, strict=True) for c in centres
           if b.x0 < c[0] + half and c[0] - half < b.x1 and b.y0 < c[1] + half and c[1] - half < b.y1]
    assert hit == []
    key = [t.get_text() for t in fig.legends[0].get_texts()]
    assert key[:3] == ["DEM", "Graph-DEM", "Pareto front"]
    assert key[3:5] == ["1  dt_50pct", "2  dt_50pct_2cores"] and key[-1] == "12  float64"
    assert not _overlap(fig.legends[0].get_window_extent(renderer), ax.get_window_extent(renderer))
    plt.close(fig)


def test_the_speedup_plot_draws_a_line_per_dem_contender(tmp_path):
    import matplotlib.image
    import pandas as pd
    table = pd.DataFrame([
        {"contender": "reference", "kind": "dem", "stable": True, "seconds_per_dem_step": 1e-3,
         "dem_steps_per_frame": 200, "cores": 1, "seconds_per_frame": np.nan},
        {"contender": "dt_50pct", "kind": "dem", "stable": True, "seconds_per_dem_step": 1e-3,
         "dem_steps_per_frame": 40, "cores": 2, "seconds_per_frame": np.nan},
        {"contender": "graphdem", "kind": "surrogate", "stable": True, "seconds_per_dem_step": np.nan,
         "dem_steps_per_frame": np.nan, "cores": 1, "seconds_per_frame": 0.01, "matched_dem": "reference"}])
    path = plots.speedup_substeps(table, "graphdem", tmp_path / "speedup.png", "speed-up")
    assert matplotlib.image.imread(path).shape[:2] == (624, 975)          # 7.5 x 4.8 inches at 130 dpi
