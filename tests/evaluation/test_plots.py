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
