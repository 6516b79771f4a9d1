"""CSV histories: round trip, undefined values."""

import numpy as np
import pytest
from mpi4py import MPI

from mpfem_fenicsx.io import History, read_csv


def test_history_round_trip_with_undefined_values(tmp_path):
    h = History(tmp_path / "history.csv", ["time", "sigma_m", "sigma_schmidt_11"], MPI.COMM_SELF)
    h.append(time=0.5, sigma_m=1.0 / 3.0, sigma_schmidt_11=np.nan)  # NaN: not defined (e.g. GDF)
    h.append(time=1.0, sigma_m=-2.5e-17, sigma_schmidt_11=4.0)
    h.write()
    lines = (tmp_path / "history.csv").read_text().splitlines()
    assert lines[0] == "time,sigma_m,sigma_schmidt_11"
    assert lines[1].endswith(",")  # written as an empty cell
    data = read_csv(tmp_path / "history.csv")
    assert data["sigma_m"][0] == 1.0 / 3.0  # exact (repr round trip)
    assert np.isnan(data["sigma_schmidt_11"][0]) and data["sigma_schmidt_11"][1] == 4.0
    with pytest.raises(KeyError, match="missing"):
        h.append(time=2.0, sigma_m=1.0)


def test_history_interrupted_while_writing_keeps_the_last_complete_file(tmp_path, monkeypatch):
    """A run killed while its history is being rewritten (every row) must leave the file of the
    row before, not a truncated one: the write stops half-way here (an exception from the CSV
    writer after a few rows) and the CSV on disk is still the complete earlier one."""
    h = History(tmp_path / "h.csv", ["a", "b"], MPI.COMM_SELF, flush_every_row=True)
    for k in range(50):
        h.append(a=k, b=2.0 * k)
    import csv

    real = csv.writer

    class Dying:
        def __init__(self, fh):
            self.inner, self.count = real(fh), 0

        def writerow(self, row):
            self.count += 1
            if self.count > 10:
                raise KeyboardInterrupt("killed while writing")
            self.inner.writerow(row)

    monkeypatch.setattr(csv, "writer", Dying)
    with pytest.raises(KeyboardInterrupt):
        h.append(a=50, b=100.0)
    monkeypatch.undo()
    data = read_csv(tmp_path / "h.csv")
    assert data["a"].size == 50
    assert np.array_equal(data["b"], 2.0 * np.arange(50))


def test_off_screen_render_prints_no_x_server_warning(tmp_path, python):
    """Every off-screen picture printed VTK's "bad X server connection" warning."""
    import subprocess

    script = (
        "import mpfem_fenicsx, pyvista\n"
        "from mpfem_fenicsx.io.render import render_grid\n"
        "grid = pyvista.Sphere().cast_to_unstructured_grid()\n"
        "grid.cell_data['von Mises (MPa)'] = range(grid.n_cells)\n"
        f"render_grid(grid, {str(tmp_path / 'sphere.png')!r})\n"
    )
    env = {k: v for k, v in __import__("os").environ.items() if k != "DISPLAY"}
    proc = subprocess.run(
        [python, "-c", script], capture_output=True, text=True, timeout=300, env=env
    )
    assert proc.returncode == 0, proc.stderr[-800:]
    assert (tmp_path / "sphere.png").stat().st_size > 1000
    assert "X server" not in proc.stderr and "WARN" not in proc.stderr, proc.stderr[-800:]


def test_progress_line_names_steps_past_the_nominal_count():
    """The progress bar: step / total within the nominal count, and the nominal count named
    when cut-backs take an implicit run past it (not '260/100')."""
    import io

    from mpi4py import MPI

    from mpfem_fenicsx.io.progress import Progress

    progress = Progress(MPI.COMM_SELF, stream=io.StringIO())
    line = progress.update(0.5, 50, 100, rho=0.7, sigma_m=2.0)
    assert "step 50/100 " in line and "50.0 %" in line
    line = progress.update(0.8, 260, 100, rho=0.85, sigma_m=9.0)
    assert "step 260 (100 nominal)" in line and "/100" not in line and "80.0 %" in line
