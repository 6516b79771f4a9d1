"""Particle and assembly meshes (importable as ``mpfem_fenicsx.meshes``)."""

from .assembly import ParticleAssembly, cell_volumes, particle_mesh, particle_volumes
from .cubesphere import UnitBallMesh, unit_ball_hex

__all__ = ["ParticleAssembly", "UnitBallMesh", "cell_volumes", "particle_mesh",
           "particle_volumes", "unit_ball_hex"]
