"""``thermonet render OUTDIR``: an off-screen PyVista picture of one frame of a run, springs as
tubes coloured by temperature (by tension when the run had no thermal coupling)."""

from __future__ import annotations

import os

import numpy as np

from ..errors import InputError
from ..io import read_pvd

HELP = "render a frame of a run's output to a PNG (springs as tubes coloured by temperature; needs PyVista)"


def add_args(p) -> None:
    p.add_argument("outdir", metavar="OUTDIR", help="output folder of a run (holding a .pvd)")
    p.add_argument("--frame", type=int, default=-1, help="frame index in the .pvd (default: the last; negative counts from the end)")
    p.add_argument("--png", default=None, metavar="FILE", help="picture file (default: OUTDIR/<frame>.png)")
    p.add_argument("--field", default=None, help="cell field to colour by (default: temperature, else tension)")
    p.add_argument("--size", default="1200x800", help="picture size WIDTHxHEIGHT in pixels")


def handle(args) -> int:
    try:
        import pyvista as pv
    except ImportError:
        raise InputError("thermonet render needs PyVista: pip install 'thermonet[vis]'") from None
    if not os.path.isdir(args.outdir):
        raise InputError(f"{args.outdir}: no such output folder")
    pvds = sorted(f for f in os.listdir(args.outdir) if f.endswith(".pvd"))
    if len(pvds) != 1:
        raise InputError(f"{args.outdir}: expected one .pvd file, found {len(pvds)}{': ' + ', '.join(pvds) if pvds else ''}")
    frames = read_pvd(os.path.join(args.outdir, pvds[0]))
    if not frames:
        raise InputError(f"{pvds[0]}: lists no frames")
    if not -len(frames) <= args.frame < len(frames):
        raise InputError(f"--frame {args.frame}: {pvds[0]} has frames 0..{len(frames) - 1}")
    time, path = frames[args.frame]
    try:
        width, height = (int(v) for v in args.size.lower().split("x"))
    except ValueError:
        raise InputError(f"--size {args.size!r}: expected WIDTHxHEIGHT, e.g. 1200x800") from None
    png = args.png or os.path.splitext(path)[0] + ".png"
    render_frame(pv, path, time, png, args.field, (width, height))
    print(png)
    return 0


def render_frame(pv, vtu_path: str, time: float, png: str, field: str | None, size) -> None:
    grid = pv.read(vtu_path)
    lines = grid.cells_dict.get(pv.CellType.LINE)
    if lines is None:
        raise InputError(f"{vtu_path}: has no line cells (springs)")
    if field is None:
        field = next((f for f in ("temperature", "tension", "strain") if f in grid.cell_data), None)
    elif field not in grid.cell_data:
        raise InputError(f"--field {field!r}: not in the frame; cell fields: {', '.join(grid.cell_data.keys())}")
    quiet_vtk_warnings()
    poly = pv.PolyData(np.asarray(grid.points), lines=np.column_stack([np.full(len(lines), 2), lines]).ravel())
    if field is not None:
        poly.cell_data[field] = np.asarray(grid.cell_data[field])
    lengths = np.linalg.norm(poly.points[lines[:, 1]] - poly.points[lines[:, 0]], axis=1)
    tubes = poly.tube(radius=0.08 * float(np.median(lengths)), n_sides=10)
    plotter = pv.Plotter(off_screen=True, window_size=list(size))
    plotter.set_background("white")
    plotter.add_mesh(tubes, scalars=field, cmap="inferno", smooth_shading=True,
                     scalar_bar_args={"title": field or "", "color": "black", **bar_labels(poly.cell_data.get(field)),
                                      "title_font_size": 18, "label_font_size": 16, "vertical": True,
                                      "position_x": 0.85, "position_y": 0.1, "height": 0.8, "width": 0.06})
    plotter.add_text(f"t = {time:.6g}", color="black", font_size=12)
    plotter.add_axes(color="black")  # the orientation marker: x, y, z
    plotter.view_isometric()
    plotter.screenshot(png)
    plotter.close()


def quiet_vtk_warnings() -> None:
    """Keep VTK's warnings (``bad X server connection`` where there is no display, before it
    falls back to off-screen rendering) out of the terminal; its errors still show."""
    try:
        from vtkmodules.vtkCommonCore import vtkLogger
    except ImportError:  # pragma: no cover - a VTK without its logger
        return
    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)


def bar_labels(values) -> dict:
    """The colour bar's label count and printf format: five labels with as many digits as tell
    them apart (``%.0f`` for 300..900, ``%.4f`` for 299.99..300.01), two equal labels for a
    field that does not vary; exponents only for very large or small values."""
    if values is None or len(values) == 0:
        return {"n_labels": 5, "fmt": "%.4g"}
    v = np.asarray(values, dtype=np.float64)
    lo, hi = float(np.nanmin(v)), float(np.nanmax(v))
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return {"n_labels": 5, "fmt": "%.4g"}
    if hi == lo:
        return {"n_labels": 2, "fmt": "%.6g"}
    step = (hi - lo) / 4
    size = max(abs(lo), abs(hi))
    if size >= 1e6 or size < 1e-3:
        digits = max(1, int(np.ceil(np.log10(size / step))) + 1)
        return {"n_labels": 5, "fmt": f"%.{min(digits, 10)}e"}
    decimals = max(0, int(np.ceil(-np.log10(step))) + 1)
    return {"n_labels": 5, "fmt": f"%.{min(decimals, 10)}f"}
