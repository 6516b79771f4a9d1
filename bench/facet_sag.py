"""The faceted particle's sag: why the cell between walls leads the periodic cell at the first rows.

    python bench/facet_sag.py                 # refinements 1-3, against the kept Newton runs

The simple cubic cell's particle meshes are inscribed in their spheres: surface nodes on the
sphere, facets inside it by up to h^2 / 8 r. A node pressed on a rigid plane meets it where the
sphere does; a node pressed on a neighbour meets the neighbour's facets, which lie inside the
neighbour's sphere, so a particle-particle contact engages later, by about the sag, than the
plane contact the walls realize at half the approach. Purely geometric, so measured here without
finite elements: two rigid particle surfaces (the chapter-2 cube-sphere in the cell's generic
orientation, refined 1-3 times) are overlapped along x, y and z by the approach delta of the
periodic die path at rho (delta = 2 r (1 - (pi / 6) / rho) per contact, one axis compressed), and
the penalty forces are summed as the contact model does (two-pass, each node's tributary area,
weight 1/2 and penalty k per pass between particles; one pass at 2 k against the plane at
delta / 2, as `workflows.tooled.tool_law` sets). The table gives, per refinement:

- the onset: the approach at which the first node touches, pair and twice the plane's (mm / r);
- the rigid-overlap force of the walls over the pair's, minus 1, at the die path's densities.

Deformation spreads a real contact (the finite-element rows differ less at a given approach),
but the onset shift and its h^2 convergence are the surfaces'. Where the kept Newton runs of
`bench/walls_vs_periodic.py` exist (bench/measured/simple_cubic_walls/, refined<N>/), their
sigma_zz row differences at the same densities are printed beside.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent
KEPT = ROOT / "measured" / "simple_cubic_walls"
DENSITIES = (0.543, 0.565, 0.60, 0.65, 0.70)


def particle_surface(refinement: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The unit chapter-2 particle in the cell's orientation: nodes (n, 3), the surface nodes'
    tributary areas (n,; 0 inside) and the surface triangles (two per quadrilateral, (m, 3))."""
    from meshes.cubesphere import RESOLUTIONS, unit_ball_hex
    from mpfem_fenicsx.workflows.simple_cubic import MESH_ROTATION

    divisions, layers = RESOLUTIONS["chapter2"]
    ball = unit_ball_hex(divisions, layers, refinement=refinement, exact_volume=False)
    x = ball.points @ MESH_ROTATION.T
    on_surface = np.zeros(len(x), bool)
    on_surface[ball.surface_nodes] = True
    # the hexahedra's six faces (lexicographic corners), those with four surface nodes, once each
    local = [[0, 1, 2, 3], [4, 5, 6, 7], [0, 1, 4, 5], [2, 3, 6, 7], [0, 2, 4, 6], [1, 3, 5, 7]]
    faces = ball.cells[:, local].reshape(-1, 4)
    faces = np.unique(np.sort(faces[on_surface[faces].all(axis=1)], axis=1), axis=0)
    # a face's corners in cyclic order about its centre (the mesh's local order aside)
    centre = x[faces].mean(axis=1)
    n = centre / np.linalg.norm(centre, axis=1, keepdims=True)
    e1 = x[faces[:, 0]] - centre
    e1 -= n * np.sum(e1 * n, axis=1, keepdims=True)
    e2 = np.cross(n, e1)
    rel = x[faces] - centre[:, None]
    angle = np.arctan2(np.einsum("fkd,fd->fk", rel, e2), np.einsum("fkd,fd->fk", rel, e1))
    quads = np.take_along_axis(faces, np.argsort(angle, axis=1), axis=1)
    a, b, c, d = (x[quads[:, k]] for k in range(4))
    quad_area = 0.5 * np.linalg.norm(np.cross(c - a, d - b), axis=1)
    area = np.zeros(len(x))
    np.add.at(area, quads.ravel(), np.repeat(quad_area / 4.0, 4))
    triangles = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    return x, area, triangles


def surface_height(x: np.ndarray, triangles: np.ndarray, points: np.ndarray, lower: bool):
    """Height (z) of the faceted surface above (x, y) of each of ``points``: its lowest point
    (``lower``) or highest; NaN where the vertical line misses it."""
    A, B, C = (x[triangles[:, k]] for k in range(3))
    v0, v1 = (B - A)[:, :2], (C - A)[:, :2]
    det = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]
    ok = np.abs(det) > 1e-14
    out = np.full(len(points), np.nan)
    for chunk in np.array_split(np.arange(len(points)), max(1, len(points) // 64)):
        v2 = points[chunk, None, :2] - A[None, :, :2]
        u = (v2[..., 0] * v1[:, 1] - v1[:, 0] * v2[..., 1]) / np.where(ok, det, 1.0)
        v = (v0[:, 0] * v2[..., 1] - v2[..., 0] * v0[:, 1]) / np.where(ok, det, 1.0)
        hit = ok & (u >= -1e-12) & (v >= -1e-12) & (u + v <= 1 + 1e-12)
        z = A[:, 2] + u * (B - A)[:, 2] + v * (C - A)[:, 2]
        z = np.where(hit, z, np.inf if lower else -np.inf)
        best = z.min(axis=1) if lower else z.max(axis=1)
        out[chunk] = np.where(np.isfinite(best), best, np.nan)
    return out


def overlap_table(refinement: int, axis: int) -> tuple[float, float, list[float]]:
    """Along ``axis``: the onset approach of the pair and twice the plane's (r = 1), and the
    walls' rigid-overlap force over the pair's, minus 1, at :data:`DENSITIES`."""
    x, area, triangles = particle_surface(refinement)
    x = x[:, [(axis + 1) % 3, (axis + 2) % 3, axis]]  # the contact axis as z
    surface = area > 0
    top = np.flatnonzero(surface & (x[:, 2] > 0.5))
    bottom = np.flatnonzero(surface & (x[:, 2] < -0.5))
    lower_half = triangles[np.all(x[triangles, 2] < 0.0, axis=1)]
    upper_half = triangles[np.all(x[triangles, 2] > 0.0, axis=1)]
    # particle A at the origin, B at 2 e_z: A's upper nodes against B's lower surface, and B's
    # lower nodes against A's upper surface (the two passes); the plane tangent at z = 1
    gap_a = 2.0 + surface_height(x, lower_half, x[top], lower=True) - x[top, 2]
    gap_b = 2.0 + x[bottom, 2] - surface_height(x, upper_half, x[bottom], lower=False)
    gap_a, gap_b = np.nan_to_num(gap_a, nan=np.inf), np.nan_to_num(gap_b, nan=np.inf)
    gap_wall = 1.0 - x[top, 2]

    def pair(delta):
        return 0.5 * (
            np.sum(area[top] * np.clip(delta - gap_a, 0.0, None))
            + np.sum(area[bottom] * np.clip(delta - gap_b, 0.0, None))
        )

    def walls(delta):
        return 2.0 * np.sum(area[top] * np.clip(0.5 * delta - gap_wall, 0.0, None))

    ratios = []
    for rho in DENSITIES:
        delta = 2.0 * (1.0 - (np.pi / 6.0) / rho)
        ratios.append(walls(delta) / pair(delta) - 1.0)
    return min(gap_a.min(), gap_b.min()), 2.0 * gap_wall.min(), ratios


def measured(refinement: int) -> list[float] | None:
    """The kept Newton runs' sigma_zz, walls over periodic minus 1, at :data:`DENSITIES`."""
    from mpfem_fenicsx.io.history import read_csv

    root = KEPT / f"refined{refinement}" if refinement > 1 else KEPT
    walls = root / "walls_newton_s80" / "history.csv"
    periodic = root / "periodic_newton_s80" / "die" / "history.csv"
    if not (walls.is_file() and periodic.is_file()):
        return None
    w, p = read_csv(walls), read_csv(periodic)
    last = min(w["rho"][-1], p["rho"][-1])
    return [
        np.interp(rho, w["rho"], w["sigma_zz_walls"]) / np.interp(rho, p["rho"], p["sigma33"]) - 1
        if rho <= last
        else np.nan
        for rho in DENSITIES
    ]


def main() -> None:
    """Print the table."""
    import sys

    sys.path.insert(0, str(ROOT.parent))  # the repository: the meshes package
    head = " | ".join(f"{rho}" for rho in DENSITIES)
    print(f"| refinement | axis | onset pair / 2 x plane (r) | walls / pair - 1 at rho {head} |")
    print("|---|---|---|" + "---|" * len(DENSITIES))
    for refinement in (1, 2, 3):
        for axis in range(3):
            pair, plane, ratios = overlap_table(refinement, axis)
            cells = " | ".join(f"{r:+.1%}" for r in ratios)
            print(f"| {refinement} | {'xyz'[axis]} | {pair:.4f} / {plane:.4f} | {cells} |")
        fe = measured(refinement)
        if fe is not None:
            cells = " | ".join("-" if np.isnan(r) else f"{r:+.1%}" for r in fe)
            print(f"| {refinement} | z, by Newton (sigma_zz) | | {cells} |")


if __name__ == "__main__":
    main()
