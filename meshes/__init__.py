"""Particle and assembly meshes (importable as ``mpfem_fenicsx.meshes``)."""

from .assembly import CellVolumes, ParticleAssembly, ParticleVolumes, particle_mesh, particle_volumes
from .cubesphere import UnitBallMesh, unit_ball_hex

__all__ = ["CellVolumes", "ParticleAssembly", "ParticleVolumes", "UnitBallMesh", "particle_mesh",
           "particle_volumes", "unit_ball_hex"]
