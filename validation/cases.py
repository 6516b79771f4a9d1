"""The validation cases and the thesis numbers they are compared with.

Every case is a ``CompactionCase`` of the thesis' chapter-2 set-up: lead (thesis table 2.1, the
library's ``LEAD``), 50 particles (seed 1), friction 0.1, explicit, d_bc per thesis table 2.3
(``mpfem_fenicsx.boundary.BOUNDARY_KINDS``: CLP 1.8 r_max, the others 2.5 r_max), and the thesis'
own particle: its appendix-A cube-sphere inscribed in the sphere (``exact_volume=False``, 2.95 %
less solid than the sphere) while rho counts the spheres' volume (eq. 2.4-2.5), so that "rho =
0.95" means what it means in the thesis. One die run (``die_CLP_exact_volume``) keeps the
library's default particle, which holds its sphere's volume, to show what that definition moves.
Each stage names its cases; a case runs into ``validation/runs/<name>/`` (``done`` written at the
end: a finished case is not repeated).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

#: thesis §2.7 (text after fig. 2.24): sigma_m (MPa) at rho = 0.95, die compaction, 50 particles
THESIS_DIE_SIGMA_M = {"GDF": 9.7, "CLPS": 11.3, "CLP": 12.6}
#: thesis table 4.2 (gamma = 1e-2 mJ/mm^2): limit specific contact surface Gamma_l (mm^-1) per rho_f
THESIS_GAMMA_L = {
    "isotropic": {0.60: 2.07, 0.70: 8.75, 0.79: 16.95, 0.87: 27.4, 0.91: 33.6, 0.95: 46.8},
    "die": {0.59: 2.09, 0.67: 7.96, 0.75: 15.58, 0.82: 24.9, 0.85: 30.0, 0.89: 39.8},
}
#: thesis §2.7 (fig. 2.25 and its text): h_v = ln(V / V0) beyond which the periodic curves
#: (CLP) rise above the non-periodic ones (GDF, GDH); the gap stays below 20 %
THESIS_DIVERGENCE_HV = {"isotropic": -0.17, "die": -0.11}
THESIS_NONPERIODIC_GAP = 0.20
#: thesis §2.7 (fig. 2.24b, d): the stress paths sigma_d(sigma_m) of the conditions are alike,
#: except GDH under die loading, whose deviatoric stress is higher at the same pressure; read at
#: these sigma_m (MPa) as the mean ratio to CLP's ("alike": within TOLERANCE; GDH: above it)
PATH_READ_AT = (2.0, 4.0, 6.0, 8.0)
#: thesis §2.4 (fig. 2.8a): h_d / |h_v| of an isotropic compaction with duplicated-particle
#: conditions, "environ 6 à 9 %"; the campaign's expectation for CLP: about 0
THESIS_GDF_DRIFT = (0.06, 0.09)
CLP_DRIFT_LIMIT = 0.03
#: imposed densities where the report reads h_d against the centroid fit's noise (isotropic)
DRIFT_READ_AT = (0.80, 0.90)
#: thesis table 2.3 / §2.5 (die loading, 50 particles): d_bc / r_max from which the results are
#: stable; CLP is studied with tied copies (periodic images do not depend on d_bc)
THESIS_STABLE_DBC = {"GDF": 2.0, "CLP": 1.8, "CLPS": 1.5}
#: + 2.5 r_max, the die stage's run; GDF 3.0: whether 2.5 itself is stable (2.0 reads 14 % below
#: it at the end; 426 copies, 476 particles in the model)
DBC_GRID = {"GDF": (1.5, 2.0, 3.0), "CLP": (1.2, 1.5, 1.8, 2.1), "CLPS": (1.0, 1.5, 2.0)}
#: "stable": sigma_m within this of the largest d_bc's run at every reading (the thesis compares
#: whole curves, fig. 2.6-2.16): along the ramp at these rho_imposed, and at the end when the
#: run passes its quasi-static check (else its end is the ramp deceleration's relaxation: CLPS)
DBC_STABLE_WITHIN = 0.02
DBC_READ_AT = (0.85, 0.90, 0.93)
#: the campaign's goal for every compared number
TOLERANCE = 0.15


#: the explicit solver's reduced mass of the constrained model
#: (``ExplicitSettings.constraint_mass``) per condition in the die and isotropic stages: CLPS with
#: the consistent P^T M P, the particles' own inertia, as Abaqus' constraint equations keep it (with
#: the row-sum lumping its die run at 6000 increments loses 42 % of its stress where the ramp
#: decelerates and fails its quasi-static check; the increments stage, validation/README.md); GDF
#: and GDH with the lumping, with which they pass their checks; CLP by periodic images has no
#: constraint to lump
STAGE_CONSTRAINT_MASS = {"CLP": "lumped", "CLPS": "consistent", "GDF": "lumped", "GDH": "lumped"}

#: the chapter-2 set-up every case starts from (its options override these)
CHAPTER2_SETUP = dict(
    particles=50,
    seed=1,
    increments=6000,
    outputs=40,
    visual=False,
    checkpoint_every=2,
    exact_volume=False,
)


@dataclass(frozen=True)
class Case:
    """One compaction run: ``name`` (its run directory) and the ``CompactionCase`` options;
    ``repeats``: the run this one repeats with more increments (``slower_case``) or another reduced
    mass (``lumped_mass_die_case``), else None."""

    name: str
    options: dict = field(default_factory=dict)
    repeats: str | None = None

    @property
    def d_bc(self) -> float:
        """Duplication distance / r_max: the case's, else its condition's (thesis table 2.3)."""
        from mpfem_fenicsx.boundary import boundary_kind

        return self.options.get("d_bc", boundary_kind(self.options["condition"]).default_d_bc)

    @property
    def increments(self) -> int:
        """Explicit increments of the run (a stress-controlled run's ``increments`` are per
        loading duration: its control lasts longer)."""
        n = self.options.get("increments", CHAPTER2_SETUP["increments"])
        control = self.options.get("control")
        if control is None:
            return n
        from mpfem_fenicsx.case import LoadingSection
        from mpfem_fenicsx.parameters import parameter_default

        return round(n * control.duration / parameter_default(LoadingSection, "duration"))

    def compaction_case(self, out_dir: str):
        """The ``CompactionCase``: the chapter-2 set-up with this case's options, in ``out_dir``."""
        from mpfem_fenicsx.workflows.compaction import CompactionCase

        return CompactionCase.build(**{**CHAPTER2_SETUP, **self.options}, directory=out_dir)


def die_case(bc: str) -> Case:
    """Die compaction ("matrice", uniaxial strain along z) to rho_f = 0.95 (thesis §2.7), with the
    condition's reduced mass (``STAGE_CONSTRAINT_MASS``)."""
    return Case(
        f"die_{bc}",
        dict(
            path="die", condition=bc, target_density=0.95, constraint_mass=STAGE_CONSTRAINT_MASS[bc]
        ),
    )


def slower_case(reference: Case, increments: int) -> Case:
    """``reference`` with ``increments`` explicit increments over the same duration: the mass-scaled
    increment shrinks as 1 / increments and the scaled masses as its square (less inertia, the same
    path). Whether the stage's 6000 increments converge its curve and end value; ``repeats`` names
    the 6000-increment run."""
    return Case(
        f"{reference.name}_n{increments}",
        {**reference.options, "increments": increments},
        repeats=reference.name,
    )


def slow_die_case(bc: str, increments: int, d_bc: float | None = None) -> Case:
    """``slower_case`` of ``die_case(bc)`` (or of ``dbc_case(bc, d_bc)``)."""
    return slower_case(die_case(bc) if d_bc is None else dbc_case(bc, d_bc), increments)


def lumped_mass_die_case(bc: str, increments: int | None = None) -> Case:
    """The die compaction of ``die_case(bc)`` with the row-sum lumped reduced mass |P|^T M |P|
    instead of the consistent P^T M P (``ExplicitSettings.constraint_mass``): the lumping hands each
    coupling's eliminated node to every master (a rigid translation of the 50-particle CLPS model
    weighs ~2.5x its particles); with ``increments`` whether its end value moves with them."""
    reference = die_case(bc)
    options = {**reference.options, "constraint_mass": "lumped"}
    if increments is not None:
        options["increments"] = increments
    return Case(
        f"{reference.name}_lumped_mass" + ("" if increments is None else f"_n{increments}"),
        options,
        repeats=reference.name,
    )


def dbc_reference_case(bc: str) -> Case:
    """The die run at the thesis' d_bc that closes the d_bc study of a condition with copies: the
    die stage's run, or its lumped-mass repeat where the die stage uses the consistent mass (the
    d_bc runs are lumped: one reduced mass along the study)."""
    reference = die_case(bc)
    return (
        reference if reference.options["constraint_mass"] == "lumped" else lumped_mass_die_case(bc)
    )


def exact_volume_die_case() -> Case:
    """Die CLP on the library's default particle, which holds its sphere's volume: rho
    = 0.95 is then 0.95 of real solid, where the thesis' faceted particles hold ~0.92."""
    return Case(
        "die_CLP_exact_volume",
        dict(path="die", condition="CLP", target_density=0.95, exact_volume=True),
    )


def isotropic_case(bc: str) -> Case:
    """Isotropic compaction to rho_f = 0.95 (thesis §2.7, fig. 2.24a-b, 2.25a), with the condition's
    reduced mass (``STAGE_CONSTRAINT_MASS``)."""
    return Case(
        f"isotropic_{bc}",
        dict(
            path="isotropic",
            condition=bc,
            target_density=0.95,
            constraint_mass=STAGE_CONSTRAINT_MASS[bc],
        ),
    )


def dbc_case(bc: str, d_bc: float) -> Case:
    """Die compaction to 0.95 at duplication distance d_bc r_max (thesis §2.5, table 2.3); CLP
    through tied copies."""
    options = dict(path="die", condition=bc, target_density=0.95, d_bc=d_bc)
    if bc == "CLP":
        options["images"] = False
    return Case(f"dbc_{bc}_{d_bc:g}", options)


def size_case(particles: int, bc: str = "GDF", seed: int = 1) -> Case:
    """Isotropic compaction of ``particles`` (thesis §2.8, fig. 2.26: GDF, 50 to 1 000); with
    bc="CLP" the periodic reference on the same packing, so that the GDF-CLP gap at each size is
    free of the packings' spread; ``seed`` another packing of the same size (the spread that a
    difference between sizes must exceed)."""
    suffix = "" if seed == 1 else f"_seed{seed}"
    return Case(
        f"size_{bc}_{particles}{suffix}",
        dict(path="isotropic", condition=bc, target_density=0.95, particles=particles, seed=seed),
    )


def adhesive_case(loading: str, delta_max: float | None = None, bc: str = "CLP") -> Case:
    """Compaction with adhesion gamma = 1e-2 mJ/mm^2 to the largest rho_f of table 4.2 (delta_max:
    the library's 0.5 um of the thesis text, or e.g. appendix A's 0.2 um). bc "GDF" is the
    thesis' own chapter-4 model (346 particles: the 50 of the volume and their copies, §4.5
    conclusion); "CLP" the periodic volume."""
    options = dict(
        path=loading, condition=bc, gamma=1e-2, target_density=max(THESIS_GAMMA_L[loading])
    )
    if delta_max is None:
        return Case(f"{loading}_{bc}_gamma1e-2", options)
    return Case(
        f"{loading}_{bc}_gamma1e-2_dmax{1e3 * delta_max:g}um", {**options, "delta_max": delta_max}
    )


def chapter4_case() -> Case:
    """The thesis' chapter-4 volume: its GDF model with adhesion (``adhesive_case("isotropic",
    bc="GDF")``) meshed with the chapter-4 particle (the 10x10 O-grid, 1 933 nodes, instead of the
    chapter-2 6x6 one), isotropic to rho_f = 0.95: how far the node-counted contact area
    (Gamma_model) moves with the thesis' own chapter-4 mesh."""
    base = adhesive_case("isotropic", bc="GDF")
    return Case(f"{base.name}_chapter4", {**base.options, "resolution": "chapter4"})


#: the calibration's triaxial test: confining pressure (MPa, near the isotropic sigma_m at rho
#: 0.79, the first fan's density) and axial strain
TRIAXIAL_CONFINING = 3.5
TRIAXIAL_AXIAL_STRAIN = 0.10


def triaxial_case(confining: float = TRIAXIAL_CONFINING) -> Case:
    """The adhesive periodic volume of the fans (CLP, gamma 1e-2) consolidated isotropically to
    ``confining`` MPa, then compressed along z by ``TRIAXIAL_AXIAL_STRAIN`` with the lateral
    stresses held (``StressPath`` "triaxial", the servo of ``demos/triaxial.py``): the path the
    calibrated continuum models replay beside the isotropic and die curves."""
    from mpfem_fenicsx.case import LoadingSection
    from mpfem_fenicsx.loading.stress_paths import StressPath
    from mpfem_fenicsx.parameters import parameter_default

    path = StressPath(
        path="triaxial",
        pressure=confining,
        axial_strain=TRIAXIAL_AXIAL_STRAIN,
        band_fraction=0.15,
    )
    control = path.control(parameter_default(LoadingSection, "duration"))
    return Case(
        f"triaxial_CLP_gamma1e-2_{confining:g}MPa",
        dict(condition="CLP", gamma=1e-2, control=control, outputs=120),
    )


def hardening_case(n: float) -> Case:
    """Die CLP compaction with the hardening exponent of the thesis' input file (0.36; table 2.1
    and the library: 0.35)."""
    from mpfem_fenicsx.material import LEAD

    return Case(
        f"die_CLP_n{n:g}",
        dict(path="die", condition="CLP", target_density=0.95, material=replace(LEAD, n=n)),
    )


@dataclass(frozen=True)
class FanCase:
    """A chapter-4 fan (thesis §4.2, ``workflows.yield_surface``) on the 50-particle CLP volume of
    the other cases: compaction (``loading``) to ``rho_f`` with adhesion ``gamma``, isotropic
    unload, ``nphi`` reloads (A = 1.5 h_v^d, eq. 4.7-4.9; the thesis drew eight, fig. 4.5). The
    loading keeps the chapter-2 runs' mean strain rate and increment: duration and increments
    scale with ln(rho_f / rho0) / ln(0.95 / rho0). The thesis' model is GDF (346 particles); a
    fan needs the periodic volume, whose macroscopic gradient is imposed."""

    name: str
    loading: str
    rho_f: float
    gamma: float = 1e-2
    nphi: int = 12
    #: reload amplitude A / h_v^d (thesis: 1.5); a larger one carries the reloads past the
    #: stress peak until contacts break, where the iso-Gamma curves can superpose (Gamma_l)
    amplitude_factor: float = 1.5
    #: fewest explicit increments of a reload (``YieldSurfaceCase.min_increments``); at 1.5 h_v^d
    #: this floor sets the reload rate, a larger one slows the reloads (the rate study)
    min_reload_increments: int = 400
    #: amplitude of the reloads in time (``YieldSurfaceCase.reload_profile``): the thesis' smooth
    #: step, or "smooth-ramps" (a constant rate over most of the reload: no point read while the
    #: reload decelerates)
    reload_profile: str = "smooth-step"
    #: the fan of the stage (sharing this one's loading) whose reloads differ from this one's in
    #: one respect, for the reload study; None: the thesis fan
    reference: str | None = None
    #: the fan whose load and unload this one reloads from (so that two fans differ in their
    #: reloads only): None for the thesis fan of the same path (a variant's default, loading
    #: afresh where that fan's state is gone), "" to load and unload itself; a fan named here
    #: must have unloaded first (``validation/run.py`` refuses otherwise)
    shares: str | None = None

    @property
    def is_thesis_fan(self) -> bool:
        """The thesis' reloads (A = 1.5 h_v^d at the default rate, smooth step), not a variant of
        them."""
        return (
            self.amplitude_factor == 1.5
            and self.min_reload_increments == 400
            and self.reload_profile == "smooth-step"
        )

    @property
    def shares_loading_with(self) -> str | None:
        """The fan whose load and unload this one reuses (same path), or None: ``shares`` if
        given, else the thesis fan of the same path for a variant."""
        if self.shares is not None:
            return self.shares or None
        return None if self.is_thesis_fan else fan_case(self.loading, self.rho_f, self.gamma).name

    @property
    def compared_with(self) -> str | None:
        """The fan this variant's surfaces are compared with: ``reference`` if given, else the
        thesis fan whose loading it shares (None for a thesis fan)."""
        return None if self.is_thesis_fan else self.reference or self.shares_loading_with

    @property
    def reload_label(self) -> str:
        """How the reloads differ from the thesis' ("" for a thesis fan), for legends."""
        return (
            (f", A {self.amplitude_factor:g} h_v^d" if self.amplitude_factor != 1.5 else "")
            + (
                f", reloads >= {self.min_reload_increments} increments"
                if self.min_reload_increments != 400
                else ""
            )
            + (f", {self.reload_profile} reloads" if self.reload_profile != "smooth-step" else "")
        )

    def yield_surface_case(self, out_dir: str):
        """This fan's ``YieldSurfaceCase`` (compaction to ``rho_f``, reloads) in ``out_dir``."""
        import math

        from mpfem_fenicsx.workflows.compaction import initial_packing
        from mpfem_fenicsx.workflows.yield_surface import YieldSurfaceCase

        chapter2 = Case("chapter2", dict(path=self.loading, condition="CLP", target_density=0.95))
        reference = chapter2.compaction_case(out_dir)
        rho0 = initial_packing(
            reference.packing, reference.mesh, reference.loading.target_density
        ).rho0
        share = math.log(self.rho_f / rho0) / math.log(0.95 / rho0)
        base = reference.updated(
            target_density=self.rho_f,
            gamma=self.gamma,
            increments=max(100, round(share * reference.solver.increments)),
            duration=share * reference.loading.duration,
            checkpoint_every=4,
        )
        return YieldSurfaceCase(
            base=base,
            nphi=self.nphi,
            amplitude_factor=self.amplitude_factor,
            min_increments=self.min_reload_increments,
            reload_profile=self.reload_profile,
            out_dir=out_dir,
        )


def fan_case(
    loading: str,
    rho_f: float,
    gamma: float = 1e-2,
    amplitude_factor: float = 1.5,
    min_reload_increments: int = 400,
    reload_profile: str = "smooth-step",
    reference: str | None = None,
    shares: FanCase | None = None,
    loads_itself: bool = False,
) -> FanCase:
    """The fan after a ``loading`` compaction to ``rho_f`` (a row of table 4.2 with gamma 1e-2);
    ``shares``: the fan of the same path whose load and unload it reloads from (its name then
    ends in ``_u<that fan's reload increments>``: its unload ran at that rate); ``loads_itself``:
    load and unload afresh, never from the thesis fan's state."""
    if shares is not None and (shares.loading, shares.rho_f, shares.gamma) != (
        loading,
        rho_f,
        gamma,
    ):
        raise ValueError(f"shares must be a fan of the same path, got {shares.name}")
    if shares is not None and loads_itself:
        raise ValueError("a fan either shares another's loading or loads itself, not both")
    name = (
        f"fan_{loading}_{rho_f:g}"
        + ("" if gamma == 1e-2 else f"_gamma{gamma:g}")
        + ("" if amplitude_factor == 1.5 else f"_A{amplitude_factor:g}")
        + ("" if min_reload_increments == 400 else f"_n{min_reload_increments}")
        + ("" if reload_profile == "smooth-step" else f"_{reload_profile.removeprefix('smooth-')}")
        + ("" if shares is None else f"_u{shares.min_reload_increments}")
    )
    return FanCase(
        name,
        loading,
        rho_f,
        gamma,
        amplitude_factor=amplitude_factor,
        min_reload_increments=min_reload_increments,
        reload_profile=reload_profile,
        reference=reference,
        shares="" if loads_itself else (shares.name if shares is not None else None),
    )


#: the campaign's densities after each loading (rows of thesis table 4.2) and the reload
#: increments of its two rates at A = 1.5 h_v^d (the die fans, at 3 h_v^d, twice these)
CALIBRATION_DENSITIES = {"isotropic": (0.70, 0.79, 0.87), "die": (0.75, 0.82, 0.89)}
CALIBRATION_INCREMENTS = (1200, 3600)


def calibration_fans() -> list[FanCase]:
    """The campaign's fans: at each density, the slower rate loads and unloads (the unload runs
    at the reloads' increments: the slower, the nearer rest) and reloads; the faster reloads
    from that same unload, so that the two differ in their reload rate only, and is compared
    with the slower. The slower ones first: each faster one waits for its unload."""
    sources, sharers = [], []
    for loading, densities in CALIBRATION_DENSITIES.items():
        factor = 1.0 if loading == "isotropic" else 2.0
        fast, slow = (int(factor * n) for n in CALIBRATION_INCREMENTS)
        amplitude = 1.5 * factor
        for rho in densities:
            options = dict(loading=loading, rho_f=rho, amplitude_factor=amplitude)
            source = fan_case(**options, min_reload_increments=slow, loads_itself=True)
            sharer = fan_case(**options, min_reload_increments=fast, shares=source)
            sources.append(replace(source, reference=sharer.name))
            sharers.append(sharer)
    return sources + sharers


#: stage -> cases; `python validation/run.py STAGE` runs them, each stage on its own
STAGES = {
    "die": [die_case(bc) for bc in ("CLP", "CLPS", "GDF", "GDH")] + [exact_volume_die_case()],
    "isotropic": [isotropic_case(bc) for bc in ("CLP", "CLPS", "GDF", "GDH")],
    "dbc": [dbc_case(bc, d) for bc, grid in DBC_GRID.items() for d in grid],
    #: the die stage's increments: CLPS (consistent mass) and GDF at 12 000; CLPS with the lumped
    #: mass, which loses 42 % of its stress as the ramp decelerates at 6000, and at 12 000; CLPS at
    #: 1.0 r_max (146 particles, lumped, the same 30-40 % end loss): the rate question at a third
    #: the cost; the isotropic CLPS at 12 000 (at 6000 it fails its quasi-static check at rest)
    "increments": [
        slow_die_case("CLPS", 12000),
        lumped_mass_die_case("CLPS"),
        lumped_mass_die_case("CLPS", 12000),
        slow_die_case("GDF", 12000),
        slow_die_case("CLPS", 12000, d_bc=1.0),
        slower_case(isotropic_case("CLPS"), 12000),
    ],
    #: with isotropic_GDF and isotropic_CLP (50 particles, seed 1); a second 50-particle packing
    #: gives the spread of the 50-particle values
    "size": [
        size_case(150),
        size_case(150, "CLP"),
        size_case(50, seed=2),
        size_case(50, "CLP", seed=2),
    ],
    "gamma": [
        adhesive_case("isotropic"),
        adhesive_case("isotropic", bc="GDF"),
        adhesive_case("die"),
        adhesive_case("die", bc="GDF"),
    ],
    #: the thesis' chapter-4 volume: its own model meshed with its chapter-4 particle (hours on
    #: both cores: python validation/run.py chapter4 under mpirun -n 2)
    "chapter4": [chapter4_case()],
    #: the thesis' contradictions: n 0.35 (table 2.1) / 0.36 (input file), delta_max 0.5 um
    #: (text) / 0.2 um (appendix A); we use 0.35 and 0.5 um
    "sensitivity": [hardening_case(0.36), adhesive_case("die", delta_max=2e-4)],
    #: chapter 4: Gamma_l of table 4.2 for two isotropic rows and one die row, and the trends of
    #: §4.3-4.5 (growth with rho_f, rotation under die loading, adhesion: sigma_m < 0 reached)
    "fans": [
        fan_case("isotropic", 0.79),
        fan_case("isotropic", 0.87),
        fan_case("die", 0.82),
        fan_case("isotropic", 0.87, gamma=0.0),
        fan_case("isotropic", 0.79, amplitude_factor=5.0),
        # the reloads' discretization: 3x slower reloads (rate), and the die fan carried to
        # 3 h_v^d at the thesis fan's rate (its yield surface is open at 1.5 h_v^d)
        fan_case("isotropic", 0.79, min_reload_increments=1200),
        fan_case("die", 0.82, amplitude_factor=3.0, min_reload_increments=800),
        # the reloads' profile: a constant strain rate, at the thesis fan's; then twice as
        # far at that rate, so that W2 <= 0 is reached at full rate, not while decelerating
        fan_case("isotropic", 0.79, reload_profile="smooth-ramps"),
        fan_case(
            "isotropic",
            0.79,
            amplitude_factor=3.0,
            min_reload_increments=800,
            reload_profile="smooth-ramps",
            reference="fan_isotropic_0.79_ramps",
        ),
    ],
    #: the continuum model's campaign (``mpfem calibrate``): fans at three densities of table
    #: 4.2 after isotropic and after die loading, each at two reload rates 3x apart from one
    #: unload (the 24-particle fan: 1200 increments within 3.0 % of 3600; the 50-particle one
    #: at 400 moves by 16 % from 1200), and the triaxial test the models replay. The die fans
    #: reload to 3 h_v^d (at 1.5 their surface is open) with twice the increments, at the
    #: isotropic fans' strain rates. About 16 core-hours in all (a 3600-increment reload or
    #: unload: 6 min on one core).
    "calibration": [*calibration_fans(), triaxial_case()],
}
#: every case of every stage by name
CASES = {case.name: case for cases in STAGES.values() for case in cases}
