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
