"""Render docs/figures/paraview_slide.png with ParaView: the last frame of one exported test sim, the DEM
coloured by speed beside the Graph-DEM rollout coloured by its per-particle error (docs/export.md).

Regenerate (from the repository root, after `snakemake -c2 results/slide/vtk --config scale=ci`;
Debian: apt-get install paraview python3-paraview xvfb):

    xvfb-run -a -s "-screen 0 1600x1200x24" pvpython docs/figures/paraview_screenshot.py \
        results/slide/vtk/slide_0003 docs/figures/paraview_slide.png

Particles are drawn as spheres of their own radius (Point Gaussian, scaled by the `radius` point data).
"""

import sys

from paraview import simple as pv

WIDTH, HEIGHT = 1400, 560


def particles(view, source, array, component, title, preset, time):
    """Show ``source`` at ``time`` in ``view`` as discs of their radius, coloured by ``array`` over its range at
    that time (with a scalar bar)."""
    view.ViewTime = time
    source.UpdatePipeline(time)
    shown = pv.Show(source, view)
    shown.SetRepresentationType("Point Gaussian")
    shown.ShaderPreset = "Sphere"
    shown.ScaleByArray = 1
    shown.SetScaleArray = ["POINTS", "radius"]
    shown.UseScaleFunction = 0
    shown.GaussianRadius = 1.0
    pv.ColorBy(shown, ("POINTS", array, component) if component else ("POINTS", array))
    lut = pv.GetColorTransferFunction(array)
    lut.ApplyPreset(preset, True)
    shown.RescaleTransferFunctionToDataRange(False, True)
    bar = pv.GetScalarBar(lut, view)
    bar.Title, bar.ComponentTitle = title, ""
    bar.Orientation, bar.WindowLocation = "Horizontal", "Lower Center"
    bar.TitleFontSize, bar.LabelFontSize, bar.ScalarBarLength = 14, 12, 0.5
    bar.TitleColor = bar.LabelColor = [0.1, 0.1, 0.1]
    shown.SetScalarBarVisibility(view, True)


def view_of(source, array, component, title, preset, time, caption):
    view = pv.CreateView("RenderView")
    view.ViewSize = [WIDTH // 2, HEIGHT]
    view.OrientationAxesVisibility = 0
    view.Background = [1.0, 1.0, 1.0]
    if hasattr(view, "UseColorPaletteForBackground"):
        view.UseColorPaletteForBackground = 0
    particles(view, source, array, component, title, preset, time)
    text = pv.Text(Text=caption)
    label = pv.Show(text, view)
    label.WindowLocation, label.FontSize, label.Color = "Upper Center", 14, [0.1, 0.1, 0.1]
    view.InteractionMode = "2D"
    pv.ResetCamera(view)
    view.CameraParallelScale *= 0.8
    return view


def main(folder: str, out: str) -> None:
    dem = pv.PVDReader(FileName=f"{folder}/dem.pvd")
    rollout = pv.PVDReader(FileName=f"{folder}/graphdem.pvd")
    last = rollout.TimestepValues[-1]
    left = view_of(dem, "velocity", "Magnitude", "speed (m/s)", "Viridis (matplotlib)", last, f"DEM, t = {last:.2f} s")
    right = view_of(rollout, "error", None, "rollout error (m)", "Inferno (matplotlib)", last,
                    f"Graph-DEM rollout, t = {last:.2f} s")
    layout = pv.CreateLayout("export")
    layout.SplitHorizontal(0, 0.5)
    layout.AssignView(1, left)
    layout.AssignView(2, right)
    layout.SetSize(WIDTH, HEIGHT)
    pv.SaveScreenshot(out, layout, ImageResolution=[WIDTH, HEIGHT], TransparentBackground=0)


if __name__ == "__main__":
    main(*sys.argv[1:3])
