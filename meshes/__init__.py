"""Particle and assembly meshes (importable as ``mpfem_fenicsx.meshes``)."""

from .assembly import (
    BodyAssembly,
    CellVolumes,
    ParticleAssembly,
    ParticleCentroids,
    ParticleVolumes,
    box_bodies_mesh,
    node_particles,
    particle_mesh,
    particle_volumes,
)
from .cubesphere import UnitBallMesh, unit_ball_hex

__all__ = [
    "BodyAssembly",
    "CellVolumes",
    "ParticleAssembly",
    "ParticleCentroids",
    "ParticleVolumes",
    "UnitBallMesh",
    "box_bodies_mesh",
    "node_particles",
    "particle_mesh",
    "particle_volumes",
    "unit_ball_hex",
]
