"""A compaction case in sections, mirroring the case file: ``[packing]``, ``[mesh]``,
``[material]``, ``[contact]``, ``[boundary]``, ``[loading]``, ``[solver]``, ``[output]``.

Each section is a dataclass whose fields are declared once with
:func:`~mpfem_fenicsx.parameters.parameter` (default, meaning, unit, allowed range); a field
declared that way is a case-file key ``[section] name`` of the same name
(:mod:`mpfem_fenicsx.cli.casefile` derives its schema from these declarations), a demo option
and a line of ``mpfem run --help``. Fields declared without :func:`parameter` are for programs
only (an in-memory packing, a mesh rotation, extra path segments, a stress control).

Each stage of the pipeline takes only the sections it needs: the packing stage the
``packing`` and ``mesh`` sections, the contact law the ``contact`` section and the material,
the loading path the ``loading`` section, the solver the ``solver`` section...
:class:`CompactionCase` holds them together and checks the rules between sections.

Units: mm, N, MPa, s, t/mm^3. Relative densities (-). Sign convention: reported stresses are
positive in compression.

Example::

    case = CompactionCase(packing=PackingSection(particles=50),
                          boundary=BoundarySection(condition="GDF"),
                          solver=SolverSection(increments=3000))
    faster = case.updated(solver={"increments": 1500}, output={"directory": "results/fast"})
    same = case.updated(increments=1500, directory="results/fast")  # field names are unique
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np

from .boundary import KINDS, boundary_kind
from .loading import PROFILES
from .material import LEAD, ElastoPlastic
from .meshes.cubesphere import RESOLUTIONS
from .meshes.packing import Packing
from .parameters import check_parameters, parameter
from .solvers import SOLVERS, solver_kind
from .solvers.constraint_mass import CONSTRAINT_MASSES

__all__ = [
    "SECTIONS",
    "BoundarySection",
    "CompactionCase",
    "ContactSection",
    "LoadingSection",
    "MeshSection",
    "OutputSection",
    "PackingSection",
    "SolverSection",
]


@dataclass(frozen=True)
class PackingSection:
    """``[packing]``: the spheres, from the seeded generator, a file or an in-memory packing.
    Radii in mm (thesis table 2.1: 0.082-0.147 mm)."""

    particles: int = parameter(24, "particles of the generated periodic packing", low=2, high=5000)
    r_min: float = parameter(
        0.082, "smallest radius of the generated packing (mm)", low=0, open_low=True
    )
    r_max: float = parameter(
        0.147, "largest radius of the generated packing (mm)", low=0, open_low=True
    )
    seed: int = parameter(1, "seed of the packing generator", low=0)
    fraction: float | None = parameter(
        None,
        "stop the generator at this solid fraction (default: jammed, ~0.63) (-)",
        kind=float,
        low=0.1,
        high=0.66,
    )
    file: str | None = parameter(
        None,
        "packing file instead of the generator: 'dx dy dz' then one 'x y z r' line "
        "per sphere (mm), or a YADE export / LAMMPS dump",
        kind=str,
    )
    #: an in-memory packing instead of the generator or the file (programs, restarts)
    spheres: Packing | None = None

    def __post_init__(self):
        check_parameters(self, "packing.")
        if self.r_max < self.r_min:
            raise ValueError(
                f"packing.r_max = {self.r_max!r} is out of range: "
                f"must be >= r_min = {self.r_min!r} mm"
            )


@dataclass(frozen=True)
class MeshSection:
    """``[mesh]``: the hexahedral cube-sphere particle (every particle holds its sphere's volume
    by default) and the radius reduction before meshing."""

    resolution: str = parameter(
        "chapter2",
        "cube-sphere particle: chapter2 = the thesis' appendix-A particle (6x6 "
        "quadrilaterals per cube face, 561 nodes), chapter4 = its 10x10 O-grid (1 933 nodes), "
        "coarse = 4x4 with 4 shell layers (517 nodes); every one holds its sphere's volume",
        choices=tuple(RESOLUTIONS),
    )
    refinement: int = parameter(
        1,
        "cube-sphere refinement: multiplies the resolution's subdivisions (chapter2: 1 = "
        "561 nodes per particle, 2 = 3 929)",
        low=1,
        high=4,
    )
    radius_factor: float = parameter(
        0.99,
        "radii shrunk by this factor before meshing: no initial interpenetration (-)",
        low=0.5,
        high=1,
    )
    divisions: int | None = parameter(
        None,
        "hexahedra per inner-cube edge (default: the resolution's; odd: the "
        "contact points of axis-aligned neighbours fall on facet centres, not nodes)",
        kind=int,
        low=1,
        high=16,
    )
    layers: int | None = parameter(
        None, "shell layers (default: the resolution's)", kind=int, low=1, high=16
    )
    #: particle meshes hold their sphere's volume (nodes moved outwards by ~1 %); False: inscribed
    #: in the sphere (e.g. touching spheres of an ordered cell with radius_factor 1)
    exact_volume: bool = True
    #: orientation of the particle meshes about their centres (None: cube-sphere axes along x, y,
    #: z): one (3, 3) orthogonal matrix for all, or one per packing particle, (n, 3, 3), a copy
    #: taking its original's; a matrix of determinant -1 mirrors the mesh. One generic rotation
    #: for all keeps identical particles exact translates of each other while their contact
    #: points fall inside facets, not on nodes (ordered packings); an ordered cell's particles
    #: mirrored across its contact planes make those planes symmetry planes of the discrete
    #: problem (:func:`~mpfem_fenicsx.workflows.simple_cubic.mirrored_rotations`)
    rotation: np.ndarray | None = field(default=None, compare=False)

    def __post_init__(self):
        check_parameters(self, "mesh.")
        if self.rotation is not None:
            Q = np.asarray(self.rotation, dtype=float)
            if (
                Q.ndim not in (2, 3)
                or Q.shape[-2:] != (3, 3)
                or not np.allclose(Q @ np.swapaxes(Q, -1, -2), np.eye(3), atol=1e-12)
            ):
                raise ValueError(
                    "mesh.rotation must be a (3, 3) or (n, 3, 3) array of orthogonal matrices"
                )

    @property
    def subdivisions(self) -> tuple[int, int]:
        """(divisions, layers) of the particle meshes: the named resolution with the overrides."""
        divisions, layers = RESOLUTIONS[self.resolution]
        return (self.divisions or divisions, self.layers or layers)


@dataclass(frozen=True)
class ContactSection:
    """``[contact]``: the contact law between particles (thesis §3.3): penalty normal contact,
    Coulomb friction, the adhesive law with asperity yield."""

    friction: float = parameter(0.1, "Coulomb friction coefficient mu (-)", low=0, high=2)
    gamma: float = parameter(0.0, "Dupre adhesion energy (mJ/mm^2)", low=0, high=1)
    delta_max: float = parameter(
        5e-4, "opening at which adhesion vanishes (mm)", low=0, high=0.01, open_low=True
    )
    asperity_yield: float = parameter(
        5.0, "asperity yield stress, p0 = 3 x it (MPa)", low=0, open_low=True
    )
    penalty_factor: float = parameter(
        10.0, "penalty k = factor x E / h, h the contact element size (-)", low=0, open_low=True
    )
    #: the thesis' law (eq. 3.14) takes k_t = k (ratio 1): an elastic slip mu x the penetration
    #: before sliding, ~1e-7 mm, which a Newton update crosses at every slip reversal; 0.01 puts
    #: it at ~0.3 % of the surface element (Abaqus' default elastic slip: 0.5 % of the element)
    #: and moves the explicit flagship's sigma_m by < 0.5 % from rho 0.70 on
    tangential_penalty_ratio: float = parameter(
        0.01,
        "tangential penalty k_t = ratio x k, the stick stiffness of Coulomb friction (-)",
        low=0,
        high=1,
        open_low=True,
    )

    def __post_init__(self):
        check_parameters(self, "contact.")


@dataclass(frozen=True)
class BoundarySection:
    """``[boundary]``: the boundary condition of the periodic volume (thesis table 2.2) and its
    duplicated particles (thesis §2.2.1)."""

    condition: str = parameter(
        "CLP",
        "GDH, GDF (driven particles), CLPS (simplified periodic) or CLP (periodic)",
        choices=tuple(KINDS),
    )
    images: bool | None = parameter(
        None,
        "CLP realized by contact with periodic images (default for CLP) or, "
        "false, by tied copies (eq. 2.14)",
        kind=bool,
    )
    d_bc: float | None = parameter(
        None,
        "duplication distance d_bc as a multiple of the largest radius r_max "
        "(default: thesis table 2.3: 1.8 CLP, 2.5 others) (-)",
        kind=float,
        low=0,
        high=10,
        open_low=True,
    )
    #: duplicate across edges and corners too (False: face copies only, e.g. the 12 copies of the
    #: ordered simple cubic cell, thesis §2.6)
    corners: bool = True
    #: carry every particle with the homogeneous flow at its centre (the unknowns are the motions
    #: relative to it). False: only the constrained nodes follow F0
    comoving: bool = True
    #: CLPS: the copies' reference points turn with their originals' (thesis eq. 2.16); False:
    #: translation coupling only (eq. 2.15)
    equal_rotations: bool = True

    def __post_init__(self):
        check_parameters(self, "boundary.")
        if self.images is True and self.condition != "CLP":
            raise ValueError(
                f"boundary.images = true realizes CLP only, got condition = {self.condition!r}"
            )

    @property
    def uses_images(self) -> bool:
        """CLP realized by contact with periodic images (no copies)."""
        return boundary_kind(self.condition).tied_nodes and self.images is not False

    def d_bc_ratio(self) -> float:
        """d_bc / r_max: the given one or the condition's default (thesis table 2.3)."""
        return self.d_bc if self.d_bc is not None else boundary_kind(self.condition).default_d_bc


@dataclass(frozen=True)
class LoadingSection:
    """``[loading]``: the macroscopic path F0(t) (thesis §2.2.3): a compaction to a target
    density, an optional hold, further segments, or a stress control."""

    path: str = parameter(
        "isotropic",
        "isotropic or die (uniaxial strain along z) compaction",
        choices=("isotropic", "die"),
    )
    target_density: float = parameter(
        0.92,
        "relative density to reach, above the packing's initial one (-)",
        low=0,
        high=1,
        open_low=True,
        open_high=True,
    )
    duration: float = parameter(1e-3, "loading time, mass-scaled (s)", low=0, open_low=True)
    profile: str = parameter(
        "smooth-ramps",
        "amplitude of the compaction in time: constant strain rate between "
        "smooth ramps, or the Abaqus smooth step (peak rate mid-path)",
        choices=tuple(PROFILES),
    )
    hold: float = parameter(
        0.0,
        "relaxation hold at the final gradient after the loading, in units of the loading "
        "duration (rows with time > duration)",
        low=0,
        high=10,
    )
    #: further segments after the compaction, ((duration s, increment gradient G (3, 3)), ...):
    #: e.g. the unload F^d and a reload F^r of thesis eq. 4.7-4.9
    segments_after: tuple = ()
    #: amplitude in time of each of ``segments_after`` (missing ones: "smooth-step")
    segment_profiles: tuple = ()
    #: mixed strain / stress control (loading.mixed.StressControl) replacing the compaction path
    #: (periodic conditions, explicit solver; the control keeps its state: one run per control)
    control: object | None = field(default=None, compare=False)

    def __post_init__(self):
        check_parameters(self, "loading.")
        if len(self.segment_profiles) > len(self.segments_after) or any(
            p not in PROFILES for p in self.segment_profiles
        ):
            raise ValueError(
                f"loading.segment_profiles must name one of {', '.join(PROFILES)} for at most the "
                f"{len(self.segments_after)} segments_after, got {self.segment_profiles}"
            )


#: the implicit solver's linear solvers (``[solver] linear_solver``) and the size up to which
#: ``auto`` factorizes (free dofs: MUMPS' memory and time grow fast beyond it)
LINEAR_SOLVERS = ("auto", "direct", "iterative")
DIRECT_SOLVER_DOFS = 300_000


@dataclass(frozen=True)
class SolverSection:
    """``[solver]``: the explicit (central differences, mass scaling, damping) or implicit
    (Newton, adaptive load steps) solver and its settings."""

    kind: str = parameter(
        "explicit",
        "explicit (central differences, mass scaling) or implicit (Newton; "
        "experimental for granular volumes)",
        choices=SOLVERS,
    )
    increments: int = parameter(6000, "explicit increments over the loading", low=10)
    steps: int = parameter(100, "implicit load steps (adaptive, cut back when Newton fails)", low=1)
    linear_solver: str = parameter(
        "auto",
        "implicit linear solver: direct (MUMPS LU), iterative (GMRES + smoothed-aggregation "
        f"AMG with the rigid-body near-nullspace) or auto (direct up to {DIRECT_SOLVER_DOFS} "
        "free dofs)",
        choices=LINEAR_SOLVERS,
    )
    damping: float = parameter(
        0.0,
        "explicit viscous damping of the particles' rigid motion relative to the imposed "
        "flow (1/duration); it drags the particles towards the affine flow and adds a "
        "rate-dependent stress",
        low=0,
    )
    local_damping: float = parameter(
        0.7,
        "explicit local non-viscous damping alpha of the particles' rigid motion "
        "(Cundall): removes oscillations, resists no steady motion (-)",
        low=0,
        high=1,
        open_high=True,
    )
    constraint_mass: str = parameter(
        "lumped",
        "explicit reduced mass of the constrained model: lumped row sums or the consistent P^T M P",
        choices=CONSTRAINT_MASSES,
    )
    regularization: float = parameter(
        0.05,
        "implicit: pseudo-time drag on a particle that fewer than 4 contacts hold, in "
        "E V_p / h^2 (V_p its volume, h the contact element size) (-)",
        low=0,
        high=1,
        open_low=True,
    )
    #: 2.5e-4: the drag's work stays below 1 % of E_p at the end of the flagship by Newton (the
    #: work falls with the drag; 5e-4 ended at 1.5 %), its sigma_m within 2 % of explicit
    held_regularization: float = parameter(
        2.5e-4,
        "implicit: the drag on a particle that 4 or more force-carrying contacts hold, in "
        "E V_p / h^2 (-)",
        low=0,
        high=1,
        open_low=True,
    )
    #: implicit: steps of each of the loading's ``segments_after`` (missing ones: the
    #: compaction's increment)
    segment_steps: tuple = ()

    def __post_init__(self):
        check_parameters(self, "solver.")
        if any(int(n) < 1 for n in self.segment_steps):
            raise ValueError(
                f"solver.segment_steps must hold >= 1 implicit steps, got {self.segment_steps}"
            )


@dataclass(frozen=True)
class OutputSection:
    """``[output]``: where the results go and how often: history rows, ParaView frames,
    checkpoints."""

    directory: str = parameter(
        "results/isotropic",
        "results folder (a case file's default: results/<case file name>; --out overrides)",
    )
    outputs: int = parameter(40, "history rows and ParaView frames", low=1, high=100000)
    every: int = parameter(
        0, "explicit: a history row every so many increments (0: from outputs)", low=0
    )
    visual: bool = parameter(True, "write ParaView files and PNG figures")
    checkpoint_every: int = parameter(10, "checkpoint every so many outputs (0: none)", low=0)
    checkpoint_keep: int = parameter(2, "newest checkpoints kept (0: all)", low=0)

    def __post_init__(self):
        check_parameters(self, "output.")


#: the case's sections in case-file order (``material`` is an ElastoPlastic, declared in
#: :mod:`mpfem_fenicsx.material.parameters`)
SECTIONS: dict[str, type] = {
    "material": ElastoPlastic,
    "packing": PackingSection,
    "mesh": MeshSection,
    "contact": ContactSection,
    "boundary": BoundarySection,
    "loading": LoadingSection,
    "solver": SolverSection,
    "output": OutputSection,
}


@dataclass(frozen=True)
class CompactionCase:
    """A compaction run of a periodic volume (thesis chapter 2), section by section; the rules
    between sections are checked here (one-line ValueError naming the fields)."""

    packing: PackingSection = field(default_factory=PackingSection)
    mesh: MeshSection = field(default_factory=MeshSection)
    material: ElastoPlastic = LEAD
    contact: ContactSection = field(default_factory=ContactSection)
    boundary: BoundarySection = field(default_factory=BoundarySection)
    loading: LoadingSection = field(default_factory=LoadingSection)
    solver: SolverSection = field(default_factory=SolverSection)
    output: OutputSection = field(default_factory=OutputSection)

    def __post_init__(self):
        for name, cls in SECTIONS.items():
            if not isinstance(getattr(self, name), cls):
                raise TypeError(
                    f"CompactionCase.{name} must be a {cls.__name__}, got {getattr(self, name)!r}"
                )
        loading, solver = self.loading, self.solver
        if len(solver.segment_steps) > len(loading.segments_after):
            raise ValueError(
                f"solver.segment_steps must hold implicit steps for at most the "
                f"{len(loading.segments_after)} loading.segments_after, got {solver.segment_steps}"
            )
        if loading.control is not None and (
            not boundary_kind(self.boundary.condition).periodic
            or not solver_kind(solver.kind).stress_control
        ):
            raise ValueError(
                f"loading.control (stress-driven components) needs boundary.condition "
                f"CLP or CLPS and "
                f"the explicit solver, got condition = {self.boundary.condition!r}, "
                f"solver.kind = {solver.kind!r}"
            )

    def updated(self, **changes: Any) -> CompactionCase:
        """A copy with some fields changed. Each keyword is a section's name (its value: a whole
        section object, or a dict of that section's fields) or a field's name (field names are
        unique across sections): ``case.updated(increments=300, directory="x")`` is
        ``case.updated(solver={"increments": 300}, output={"directory": "x"})``."""
        sections: dict[str, dict[str, Any]] = {}
        whole: dict[str, Any] = {}
        for name, value in changes.items():
            if name in SECTIONS:
                if isinstance(value, dict):
                    sections.setdefault(name, {}).update(value)
                else:
                    whole[name] = value
            elif name in FIELD_SECTION:
                sections.setdefault(FIELD_SECTION[name], {})[name] = value
            else:
                raise TypeError(f"CompactionCase has no section or field {name!r}")
        for name, change in sections.items():
            whole[name] = replace(whole.get(name, getattr(self, name)), **change)
        return replace(self, **whole)

    @classmethod
    def build(cls, **keys: Any) -> CompactionCase:
        """A case from the defaults and ``keys`` as in :meth:`updated`:
        ``CompactionCase.build(particles=50, condition="GDF", increments=3000)``."""
        return cls().updated(**keys)


#: the section of every field name (unique across the sections; the material's fields excluded)
FIELD_SECTION: dict[str, str] = {
    f.name: name for name, cls in SECTIONS.items() if cls is not ElastoPlastic for f in fields(cls)
}
if len(FIELD_SECTION) != sum(len(fields(c)) for c in SECTIONS.values() if c is not ElastoPlastic):
    raise TypeError(
        "a field name repeats across the case's sections: CompactionCase.updated needs them unique"
    )
