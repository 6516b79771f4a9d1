"""Flagship demo: isotropic compaction of a periodic volume of lead particles (thesis chapter 2).

    python demos/isotropic.py
        # embedded default: 24 particles, CLP, rho -> 0.92
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
E_contact, E_visc, E_damp, W_ext (mJ); unbalanced, E_c_over_E_int (quasi-static measures);
wall_time), packing.txt (the packing used),
particles.xdmf (ParaView: displacement, von Mises, eps_p, particle id) and particles.png
(deformed particles coloured by von Mises stress). Columns are defined in
mpfem_fenicsx/workflows/history_recorder.py.
"""

from mpi4py import MPI

from mpfem_fenicsx.io.progress import Progress
from mpfem_fenicsx.options import compaction_case, compaction_parser, report_compaction, run_exits
from mpfem_fenicsx.workflows.compaction import CompactionRun


def main(argv=None, loading: str = "isotropic", doc: str = __doc__) -> None:
    comm = MPI.COMM_WORLD
    say = print if comm.rank == 0 else (lambda *a, **k: None)

    # 1. The case, section by section as in a case file ([packing], [mesh], [contact], [boundary],
    #    [loading], [solver], [output]): each option is a declared parameter, checked against its
    #    range (exit 2 with one line naming it)
    args = compaction_parser(loading, doc).parse_args(argv)
    case = compaction_case(args, loading)
    say(
        f"case: {case.packing.particles} particles, {case.boundary.condition}, "
        f"{case.loading.path} to rho = {case.loading.target_density}, "
        f"{case.solver.kind} solver ({case.solver.increments} increments)"
    )

    with run_exits():  # exit 2 on bad input found while building, 3 if the run diverges
        # 2. The model, each stage taking the sections it needs (build_compaction): the packing
        #    (rho0 = V_p / V0, thesis eq. 2.5) -> duplicated particles (none for CLP by periodic
        #    images) -> one DOLFINx mesh of cube-sphere particles -> the Hencky / von Mises bulk
        #    problem -> the periodic constraints on F0(t) (eq. 2.14) + penalty / Coulomb / adhesive
        #    contact; then the solver (make_solver: explicit central differences, mass scaling,
        #    local damping), the history recorder and the checkpoints
        run = CompactionRun(case, comm, say, restart=args.restart, progress=Progress(comm))
        # 3. The loop: increments to the target density, a history row per output, checkpoints.
        #    demos/cubic_cell.py spells every stage out on the 8-sphere simple cubic cell
        result = run.run()

    # 4. Post-processing: the end state (history.csv holds every row, particles.png the picture)
    report_compaction(result, say)


if __name__ == "__main__":
    main()
