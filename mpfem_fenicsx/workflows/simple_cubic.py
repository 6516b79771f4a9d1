"""The simple cubic cell of thesis §2.6 as a compaction case, and its verification quantities.

Eight spheres of radius r in a periodic cube of side 4 r (``meshes.packing.simple_cubic_packing``),
CLP by tied copies, every particle mesh an exact translate of the others: the motion stays
affine, so rho = pi / (6 det F) (eq. 2.17), the least-squares Hencky strain equals the
auxiliary-node one, and Love-Weber (eq. 2.6) equals Schmidt (eq. 2.19) at rest. Used by
``demos/simple_cubic.py``, the tests and the benchmarks.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ..homogenization import hencky_strain
from ..meshes.packing import simple_cubic_packing
from .compaction import CompactionCase

__all__ = ["COMPONENTS", "MESH_ROTATION", "checks", "simple_cubic_case"]

#: one generic orientation for every particle mesh (0.3 rad about (1, 2, 3)): identical particles
#: stay exact translates while their contact points are inside facets (no node-on-node contact)
MESH_ROTATION = Rotation.from_rotvec(0.3 * np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)).as_matrix()
COMPONENTS = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)]


def simple_cubic_case(
    loading: str,
    radius: float = 0.1,
    target_density: float = 0.95,
    increments: int = 4000,
    out_dir: str = "results/simple_cubic",
    visual: bool = True,
    outputs: int = 40,
    face_copies_only: bool = False,
) -> CompactionCase:
    """The thesis §2.6 cell: CLP by copies, radii not shrunk (exact pi / 6; the particle meshes are
    inscribed in their touching spheres), all copies (or the 12 face copies of the thesis)."""
    return CompactionCase.build(
        spheres=simple_cubic_packing(radius),
        path=loading,
        condition="CLP",
        images=False,
        exact_volume=False,
        corners=not face_copies_only,
        d_bc=1.0,
        radius_factor=1.0,
        rotation=MESH_ROTATION,
        target_density=target_density,
        increments=increments,
        outputs=outputs,
        visual=visual,
        directory=str(Path(out_dir) / loading),
    )


def checks(result) -> dict[str, np.ndarray]:
    """The thesis §2.6 verification quantities along the history of a simple cubic run."""
    h = result.history
    path = result.model.path
    t = h.column("time")
    F = h.tensor("F")
    F0 = np.stack([path(ti) for ti in t])
    h_lsq, h_aux = hencky_strain(F), hencky_strain(F0)
    schmidt = np.stack([h.column(f"sigma_schmidt_{i}{i}") for i in (1, 2, 3)], axis=1).mean(axis=1)
    out = {"time": t, "rho": h.column("rho"), "rho_pi6": np.pi / (6.0 * np.linalg.det(F))}
    for a, b in COMPONENTS:
        out[f"h_lsq_{a + 1}{b + 1}"] = h_lsq[:, a, b]
        out[f"h_aux_{a + 1}{b + 1}"] = h_aux[:, a, b]
    out["sigma_m_love_weber"] = h.column("sigma_m")
    out["sigma_m_schmidt"] = schmidt
    return out
