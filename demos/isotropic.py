"""Flagship demo: isotropic compaction of a periodic volume of lead particles (thesis chapter 2).

    python demos/isotropic.py                       # embedded default: 24 particles, CLP, rho -> 0.92
    python demos/isotropic.py --particles 50 --target-density 0.95 --bc CLP
    mpirun -n 2 python demos/isotropic.py --bc GDF

Pipeline: seeded frictionless packing (or --packing FILE) -> duplicated particles (d_bc rule,
thesis §2.2.1; none for CLP by periodic images, the default) -> one DOLFINx mesh of hexahedral
cube-sphere particles (the thesis' appendix-A particle, volume-exact) -> Hencky/von Mises bulk +
penalty/Coulomb/adhesive contact -> GDH/GDF/CLPS/CLP as PETSc multipoint constraints ->
explicit central differences with mass scaling and local damping -> history and pictures.

Outputs in --out (default results/isotropic/): history.csv (one row per output: time; rho =
V_p / (V0 det F) with the spheres' volumes (thesis eq. 2.4-2.5), rho_imposed, rho_fe (mesh
volumes); h_v, h_d, h_tilde_d (Hencky strain of the least-squares gradient F of the centroids);
sigma_m, sigma_d, sigma_tilde_d (Love-Weber, compression > 0); F11..F33; sigma11..33 (Love-Weber);
sigma_schmidt_11..33 (auxiliary-node reactions, CLP/CLPS, empty otherwise); n_contacts; Gamma
(specific contact surface, 1/mm); energies E_p, E_f, E_d = E_p + E_f, E_c (kinetic), E_int, E_el,
E_contact, E_visc, E_damp, W_ext (mJ); unbalanced, E_c_over_E_int (quasi-static measures); wall_time), packing.txt (the packing used),
particles.xdmf (ParaView: displacement, von Mises, eps_p, particle id) and particles.png
(deformed particles coloured by von Mises stress). Columns are defined in
mpfem_fenicsx/workflows/history_recorder.py.
"""

from mpi4py import MPI

from mpfem_fenicsx.cli.compaction import case_from_args, parser, report, run_exits
from mpfem_fenicsx.io.progress import Progress
from mpfem_fenicsx.workflows.compaction import CompactionRun


def main(argv=None) -> None:
    comm = MPI.COMM_WORLD
    say = print if comm.rank == 0 else (lambda *a, **k: None)

    # 1. The case: the options (case-file keys, checked against their ranges) -> a CompactionCase
    args = parser("isotropic", __doc__).parse_args(argv)
    case = case_from_args(args, "isotropic")

    with run_exits():  # exit 2 on bad input found while building, 3 if the run diverges
        # 2. The model: packing -> particle mesh -> bulk problem -> CLP constraints + contact; the
        #    explicit solver, the history recorder and the checkpoints on it
        run = CompactionRun(case, comm, say, restart=args.restart, progress=Progress(comm))
        # 3. The loop: increments to the target density, a history row per output, checkpoints
        result = run.run()

    # 4. Post-processing: the end state (history.csv holds every row, particles.png the picture)
    report(result, args, say)


if __name__ == "__main__":
    main()
