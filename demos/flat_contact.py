"""Flat-contact check of the adhesive and frictional contact law (thesis §3.4.1, fig. 3.6-3.8).

    python demos/flat_contact.py [--out results/flat_contact]

Writes <out>/normal.csv (delta_mm, T1_MPa, alpha), <out>/tangential.csv (u3_mm, tau_MPa,
W_f_mJ_per_mm2) and <out>/flat_contact.png, and prints the checks of the thesis: alpha = 0.5 at
T1 = 3 sigma_y, peak tension 0.5 sigma_c, zero traction from delta_max, slip onset at
u3c = 2 (1 + nu) h tau_c / E, dissipation = tau_c x accumulated slip.
"""

import argparse
from pathlib import Path

import numpy as np
from mpi4py import MPI

from mpfem_fenicsx.workflows.flat_contact import FlatContactCase, run_flat_contact


def summarize(case: FlatContactCase, normal, tangential, u3c, tau_c) -> dict:
    a = normal.array()
    delta, T1, alpha = a[:, 0], a[:, 1], a[:, 2]
    imax = T1.argmax()
    law = case.law()
    # softening branch: delta_1 < delta < delta_max, a straight line through (delta_max, 0)
    d1 = alpha[imax] * law.sigma_c / law.penalty
    soft = (delta > 2 * d1) & (delta < 0.95 * case.delta_max) & (T1 < 0)
    slope, intercept = np.polyfit(delta[soft], T1[soft], 1)
    beyond = delta >= case.delta_max
    t = tangential.array()
    u3, tau, wf = t[:, 0], t[:, 1], t[:, 2]
    stick = np.abs(tau) < 0.9 * tau_c
    first = slice(0, int(np.argmax(u3)) + 1)
    k_stick = np.polyfit(u3[first][stick[first]], tau[first][stick[first]], 1)[0]
    return {
        "T1_max_MPa": T1[imax],
        "alpha_at_T1_max": alpha[imax],
        "peak_tension_MPa": -T1.min(),
        "peak_tension_from_softening_line_MPa": -(slope * d1 + intercept),
        "zero_crossing_of_softening_mm": -intercept / slope,
        "delta_max_mm": case.delta_max,
        "max_abs_T1_beyond_delta_max": float(np.abs(T1[beyond]).max()) if beyond.any() else np.nan,
        "alpha_beyond_delta_max": float(alpha[beyond].max()) if beyond.any() else np.nan,
        "sigma_c_MPa": law.sigma_c,
        "tau_c_MPa": tau_c,
        "tau_plateau_MPa": float(np.abs(tau).max()),
        "u3c_expected_mm": u3c,
        "u3c_from_stick_slope_mm": tau_c / k_stick,
        "W_f_mJ_per_mm2": wf[-1],
        "W_f_expected_mJ_per_mm2": 6.0 * tau_c * u3c,
    }


def plot(normal, tangential, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    a, t = normal.array(), tangential.array()
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
    ax[0].plot(1e3 * a[:, 0], a[:, 1], ".-")
    ax[0].set_xlabel("normal gap delta (um)")
    ax[0].set_ylabel("T1 (MPa, compression > 0)")
    ax[0].set_title("normal law (alpha = 0.5)")
    ax[1].plot(1e3 * t[:, 0], t[:, 1], ".-")
    ax[1].set_xlabel("tangential displacement u3 (um)")
    ax[1].set_ylabel("tau (MPa)")
    ax[1].set_title("Coulomb friction, mu = 0.1")
    for a_ in ax:
        a_.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--out", default="results/flat_contact")
    args = parser.parse_args(argv)
    comm = MPI.COMM_WORLD
    case = FlatContactCase()
    normal, tangential, u3c, tau_c = run_flat_contact(case, args.out, comm)
    if comm.rank == 0:
        for key, value in summarize(case, normal, tangential, u3c, tau_c).items():
            print(f"{key:40s} {value:.6g}")
        plot(normal, tangential, Path(args.out) / "flat_contact.png")
        print(f"wrote {args.out}/normal.csv, tangential.csv, flat_contact.png")


if __name__ == "__main__":
    main()
