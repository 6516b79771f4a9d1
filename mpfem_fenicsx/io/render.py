"""Off-screen pyvista rendering of the deformed particles coloured by a cell field."""

from __future__ import annotations

from pathlib import Path

import numpy as np

import dolfinx
import dolfinx.plot


def render_deformed(
    u: dolfinx.fem.Function,
    cell_field: dolfinx.fem.Function,
    path: str | Path,
    *,
    title: str = "",
    label: str = "von Mises (MPa)",
    cells: np.ndarray | None = None,
    save_grid: bool = False,
) -> Path | None:
    """Render u-deformed particles coloured by a DG0 field to a PNG (gathered on rank 0);
    ``cells``: the local cells to show (default: all owned cells). ``save_grid``: also write the
    deformed grid next to the PNG (``.vtu``, title in its field data) so that
    :func:`render_grid_file` can draw it again without the run (``mpfem plot``)."""
    import pyvista

    mesh = u.function_space.mesh
    comm = mesh.comm
    num_cells = mesh.topology.index_map(mesh.topology.dim).size_local
    if cells is None:
        cells = np.arange(num_cells, dtype=np.int32)
    cells = np.asarray(cells, dtype=np.int32)
    topology, cell_types, x = dolfinx.plot.vtk_mesh(u.function_space, cells)
    nodes = x.shape[0]
    displacement = u.x.array.reshape(-1, 3)[:nodes]
    values = cell_field.x.array[cell_field.function_space.dofmap.list[cells, 0]]
    parts = comm.gather((topology, cell_types, x, displacement, values), root=0)
    if comm.rank != 0:
        return None
    grids = []
    for top, types, pts, disp, val in parts:
        grid = pyvista.UnstructuredGrid(top, types, pts + disp)
        grid.cell_data[label] = val
        grids.append(grid)
    grid = grids[0] if len(grids) == 1 else grids[0].merge(grids[1:])
    path = Path(path)
    if save_grid:
        grid.field_data["title"] = [title]
        grid.save(str(path.with_suffix(".vtu")))
    return render_grid(grid, path, title=title, label=label)


def render_grid(grid, path: str | Path, *, title: str = "", label: str = "von Mises (MPa)") -> Path:
    """Off-screen picture of a pyvista grid coloured by its cell array ``label``, with a scalar
    bar (title = the label with its unit) and axes."""
    import pyvista
    from vtkmodules.vtkCommonCore import vtkLogger

    # off screen without an X server VTK logs "bad X server connection" on every render (a
    # warning only: it falls back to its off-screen context); keep its errors
    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)
    pyvista.OFF_SCREEN = True
    plotter = pyvista.Plotter(off_screen=True, window_size=(1000, 800))
    plotter.add_mesh(
        grid,
        scalars=label,
        cmap="viridis",
        show_edges=True,
        edge_color="#333333",
        scalar_bar_args={
            "title": label,
            "vertical": True,
            "position_x": 0.82,
            "position_y": 0.15,
            "width": 0.08,
            "height": 0.7,
        },
    )
    if title:
        plotter.add_text(title, font_size=11)
    plotter.view_isometric()
    plotter.reset_camera()
    plotter.camera.zoom(1.1)
    plotter.show_axes()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    plotter.screenshot(str(path))
    plotter.close()
    return path


def render_grid_file(vtu: str | Path, path: str | Path, label: str = "von Mises (MPa)") -> Path:
    """Render a grid saved by :func:`render_deformed` (``save_grid=True``) to ``path``."""
    import pyvista

    grid = pyvista.read(str(vtu))
    title = str(grid.field_data["title"][0]) if "title" in grid.field_data else ""
    return render_grid(grid, path, title=title, label=label)
