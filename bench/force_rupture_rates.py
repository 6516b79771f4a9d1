"""Force-controlled rupture against strain-driven tension at several rates.

    python bench/force_rupture_rates.py                              # every probe below
    python bench/force_rupture_rates.py --probes force:1 strain:5    # some of them

The adhesive simple cubic cell (8 lead spheres, gamma = 1e-2 mJ/mm^2, 1000 increments per 1e-3 s)
is consolidated to 2 MPa and unloaded to 0.2 MPa under stress control (workflows.stress_probes),
then pulled along z with the lateral stresses held at 0.2 MPa:
- ``force:K``: sigma_33 driven linearly to -6 MPa over K x 1e-3 s (workflows.force_rupture); the
  table gives sigma_33 where E_c / E_d reaches 1e-3, where W2 turns <= 0, and at the peak;
- ``strain:R``: F33 at R 1/s over 0.03 strain (mixed control: the lateral stresses servo-held);
  the table gives the largest tension and the strain where it is reached, and the stress where
  the tangent modulus first drops below 62 MPa and 15.5 MPa (the stress rates of force:1 and
  force:4 over the servo's largest strain rate, 100 1/s: where force control must lose the path).
Every probe restarts from one consolidated state in ``--out``. MPa, compression > 0.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace

import numpy as np
from mpfem_fenicsx.meshes.packing import simple_cubic_packing
from mpi4py import MPI

from mpfem_fenicsx.loading.mixed import StressControl, normal_stress_path
from mpfem_fenicsx.workflows.compaction import CompactionCase
from mpfem_fenicsx.workflows.force_rupture import ForceRuptureCase, rupture_points, rupture_rows
from mpfem_fenicsx.workflows.stress_probes import consolidate, run_probe

START, FINAL = np.full(3, 0.2), np.array([0.2, 0.2, -6.0])


def main(argv=None) -> int:
    """Run the rupture probes on the consolidated cell, print a line per probe; return 0."""
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument(
        "--probes", nargs="+", default=["force:1", "force:4", "strain:100", "strain:20", "strain:5"]
    )
    p.add_argument("--out", default="results/force_rupture_rates")
    args = p.parse_args(argv)
    base = CompactionCase.build(
        spheres=simple_cubic_packing(),
        condition="CLP",
        d_bc=0.8,
        images=False,
        exact_volume=False,
        gamma=1e-2,
        duration=1e-3,
        increments=1000,
        outputs=10,
        visual=False,
        directory=args.out,
    )
    case = ForceRuptureCase(
        base=base,
        p_load=2.0,
        p_probe=0.2,
        final_stress=tuple(FINAL),
        rows_per_probe=40,
        out_dir=args.out,
    )
    state = consolidate(case, MPI.COMM_SELF, log=lambda *a: None)

    def quiet(*a, **k):
        return None

    for spec in args.probes:
        kind, value = spec.split(":")
        value = float(value)
        wall = time.perf_counter()
        if kind == "force":
            probe = replace(case, probe=value)
            control = normal_stress_path(
                [state.time, state.time + value * 1e-3], [START, FINAL], **probe.servo()
            )
            h = run_probe(probe, state, control, f"force_{value:g}", MPI.COMM_SELF, log=quiet)
            points = rupture_points(
                rupture_rows(h, state.time, START, FINAL, case.w2_window), case.phi_c
            )
            found = "  ".join(f"{k} {v['sigma_33']:.3f}" for k, v in points.items())
            print(
                f"{spec:12s} sigma_33 at {found}  ({time.perf_counter() - wall:.0f} s)", flush=True
            )
        else:
            duration = 0.03 / value
            pull = StressControl(
                duration=state.time + duration,
                stress_driven=np.diag([True, True, False]),
                target=lambda t: 0.2 * np.eye(3),
                velocity_gradient=lambda t, r=value: np.diag([0, 0, r]),
                **case.servo(),
            )
            h = run_probe(
                replace(case, probe=duration / 1e-3),
                state,
                pull,
                f"strain_{value:g}",
                MPI.COMM_SELF,
                log=quiet,
            )
            after = h.column("time") > state.time * (1 + 1e-12)
            tension, h33 = -h.column("sigma_schmidt_33")[after], np.log(h.column("F33")[after])
            K_t = np.diff(tension) / np.diff(h33)
            knees = []
            for limit in (62.0, 15.5):
                k = np.flatnonzero((K_t < limit) & (np.arange(K_t.size) > 0))
                knees.append(f"{tension[k[0]]:.3f}" if k.size else "-")
            k = int(np.argmax(tension))
            print(
                f"{spec:12s} largest tension {tension[k]:.3f} at strain {h33[k] - h33[0]:.4f}; K_t "
                "< 62 MPa from "
                f"{knees[0]}, < 15.5 MPa from {knees[1]}  ({time.perf_counter() - wall:.0f} s)",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
