"""Homogenization of a granular volume: mesoscopic strain and stress (thesis §2.3, §2.6, ch. 4,
appendix C). Pure numpy: plain arrays in, plain arrays out, no dolfinx / PETSc.

Units mm, N, MPa, mJ. Sign conventions:
- strains (F, h, h_v, h_d, h~_d) keep their natural sign: compaction gives h_v < 0;
- stress TENSORS (Love-Weber, Schmidt, Piola -> Cauchy, W2 increments) are in the mechanics
  convention, tension > 0, as the finite-element model gives them;
- REPORTED stress scalars (sigma_m, sigma_d, sigma~_d) are compression > 0 (thesis, soil
  mechanics); ``reported_stress(sigma) = -sigma`` for a whole tensor.
- Rendulic values use an axial (loading) axis, default e3 (index 2, the die axis).
"""

from .strain import (
    AXIAL,
    axis_vector,
    cell_vectors,
    copy_centroids,
    current_volume,
    deviator,
    gradient_fit_noise_hd,
    hencky_strain,
    least_squares_gradient,
    relative_density,
    rendulic_strain,
    solid_volume,
    specific_contact_surface,
    strain_invariants,
)
from .stress import (
    BOUNDARY_CONDITIONS,
    branch_vectors,
    contact_weights,
    coordination,
    dissipated_energy,
    first_crossing,
    love_weber_stress,
    piola_to_cauchy,
    rendulic_stress,
    reported_stress,
    row_increments,
    schmidt_piola,
    schmidt_stress,
    second_order_work,
    stress_invariants,
    uniaxial_strengths,
)

__all__ = [
    "AXIAL",
    "BOUNDARY_CONDITIONS",
    "axis_vector",
    "branch_vectors",
    "cell_vectors",
    "contact_weights",
    "coordination",
    "copy_centroids",
    "current_volume",
    "deviator",
    "gradient_fit_noise_hd",
    "dissipated_energy",
    "first_crossing",
    "hencky_strain",
    "least_squares_gradient",
    "love_weber_stress",
    "piola_to_cauchy",
    "relative_density",
    "rendulic_strain",
    "rendulic_stress",
    "reported_stress",
    "schmidt_piola",
    "schmidt_stress",
    "row_increments",
    "second_order_work",
    "solid_volume",
    "specific_contact_surface",
    "strain_invariants",
    "stress_invariants",
    "uniaxial_strengths",
]
