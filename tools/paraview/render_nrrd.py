"""Render a loom NRRD export with ParaView (pvpython), headless.

    xvfb-run -a pvpython tools/paraview/render_nrrd.py TILE.density.nrrd \
        -o OUT.png [--size WxH] [--kind TILE.kind.nrrd] [--iso D] [--volume]

Reads loom's NRRD0004 files (`loom export --format nrrd`) with ParaView's
own NRRD reader, which takes the voxel spacing and origin (millimetres)
from the header.  Draws the yarn surface as an isosurface (contour) of
density at --iso (default 0.2); with --kind (the tile's kind channel,
1 warp, 2 weft) warps and wefts are contoured separately and coloured
blue and cream, otherwise the surface is coloured by height (viridis,
lowest to highest point of the surface).  --volume draws a volume
rendering of density instead of the contour (--kind is then unused).  The camera
looks down from above at an angle, over the tile's centre.
"""
import argparse
import sys

from paraview.simple import (ColorBy, Contour, CreateView, Elevation, GetColorTransferFunction,
                             GetOpacityTransferFunction, OpenDataFile,
                             PythonCalculator, ResetCamera, SaveScreenshot, Show)


def fail(msg):
    sys.stderr.write("render_nrrd.py: %s\n" % msg)
    sys.exit(1)


def size_arg(text):
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError("expected WxH, e.g. 800x500, got %r" % text)
    if not (16 <= w <= 8192 and 16 <= h <= 8192):
        raise argparse.ArgumentTypeError("size %r out of 16..8192" % text)
    return w, h


def open_nrrd(path, what):
    try:
        r = OpenDataFile(path)
    except RuntimeError as e:
        fail("%s: ParaView cannot open this file (%s): %s" % (path, what, str(e).strip()))
    if r is None:
        fail("%s: ParaView cannot open this file (%s)" % (path, what))
    r.UpdatePipeline()
    if r.GetDataInformation().GetNumberOfPoints() == 0:
        fail("%s: no voxels read (%s)" % (path, what))
    return r


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("density", help="loom NRRD density tile (.nrrd)")
    ap.add_argument("-o", "--output", required=True, help="PNG to write")
    ap.add_argument("--size", type=size_arg, default=(800, 500), help="WxH pixels (default 800x500)")
    ap.add_argument("--kind", help="the same tile's kind channel: colour warps and wefts")
    ap.add_argument("--iso", type=float, default=0.2, help="density of the yarn surface (default 0.2)")
    ap.add_argument("--volume", action="store_true", help="volume rendering instead of the contour")
    a = ap.parse_args()
    if not 0.0 < a.iso < 1.0:
        fail("--iso %g: expected a density in (0, 1)" % a.iso)

    dens = open_nrrd(a.density, "density")
    arr = dens.PointData.keys()[0]
    lo, hi = dens.PointData[arr].GetRange()
    b = dens.GetDataInformation().GetBounds()

    view = CreateView("RenderView")
    view.ViewSize = list(a.size)
    view.OrientationAxesVisibility = 0
    view.Background = [0.92, 0.92, 0.90]
    try:
        view.UseColorPaletteForBackground = 0
    except AttributeError:
        pass

    if a.volume:
        d = Show(dens, view)
        d.SetRepresentationType("Volume")
        ColorBy(d, ("POINTS", arr))
        lut = GetColorTransferFunction(arr)
        lut.ApplyPreset("Inferno (matplotlib)", True)
        lut.RescaleTransferFunction(0.0, max(hi, 1e-6))
        otf = GetOpacityTransferFunction(arr)
        otf.Points = [0.0, 0.0, 0.5, 0.0, a.iso * 0.5, 0.0, 0.5, 0.0,
                      max(hi, 1e-6), 1.0, 0.5, 0.0]
        lut.AutomaticRescaleRangeMode = "Never"
    elif a.kind:
        kind = open_nrrd(a.kind, "kind")
        colours = {1: [0.16, 0.32, 0.62], 2: [0.93, 0.86, 0.70]}  # warp blue, weft cream
        for k, rgb in colours.items():
            masked = PythonCalculator(Input=[dens, kind], ArrayName="yarn%d" % k,
                                      Expression="inputs[0].PointData['%s'] * (inputs[1].PointData['%s'] == %d)"
                                      % (arr, kind.PointData.keys()[0], k))
            c = Contour(Input=masked, ContourBy=["POINTS", "yarn%d" % k], Isosurfaces=[a.iso])
            c.ComputeScalars = 0
            s = Show(c, view)
            ColorBy(s, None)
            s.DiffuseColor = rgb
            s.AmbientColor = rgb
            s.Specular = 0.15
    else:
        c = Contour(Input=dens, ContourBy=["POINTS", arr], Isosurfaces=[a.iso])
        c.ComputeScalars = 0
        c.UpdatePipeline()
        zb = c.GetDataInformation().GetBounds()[4:6]  # the surface's own height range
        e = Elevation(Input=c, LowPoint=[0, 0, zb[0]], HighPoint=[0, 0, zb[1]])
        s = Show(e, view)
        ColorBy(s, ("POINTS", "Elevation"))
        lut = GetColorTransferFunction("Elevation")
        lut.ApplyPreset("Viridis (matplotlib)", True)
        lut.RescaleTransferFunction(0.0, 1.0)

    cx, cy, cz = (b[0] + b[1]) / 2, (b[2] + b[3]) / 2, (b[4] + b[5]) / 2
    span = max(b[1] - b[0], b[3] - b[2])
    cam = view.GetActiveCamera()
    cam.SetFocalPoint(cx, cy, cz)
    # above the tile, tilted 35 degrees from vertical towards -y, y up in the picture
    cam.SetPosition(cx, cy - 0.9 * span, cz + 1.3 * span)
    cam.SetViewUp(0, 1, 0)
    view.CameraParallelProjection = 0
    ResetCamera(view)
    cam.Dolly(1.4)
    SaveScreenshot(a.output, view, ImageResolution=list(a.size), CompressionLevel="9")
    e = dens.GetDataInformation().GetExtent()
    print("%s: %s, %d x %d x %d voxels, density %.3g..%.3g, voxel centres %.3f..%.3f x %.3f..%.3f x %.3f..%.3f mm"
          % (a.output, a.density, e[1] - e[0] + 1, e[3] - e[2] + 1, e[5] - e[4] + 1, lo, hi, *b))


if __name__ == "__main__":
    main()
