"""MuJoCo primitive geoms as triangle meshes (for formats that carry geometry).

Each function returns ``(positions (N, 3), normals (N, 3), triangles (M, 3))`` in the geom's
own frame [m], counter-clockwise seen from outside. ``segments`` sets the resolution
around the axis.
"""

from __future__ import annotations

import mujoco
import numpy as np

SEGMENTS = 24


def _grid(rings: list[tuple[float, float, float]], segments: int):
    """A surface of revolution about z: ``rings`` are (radius, z, normal angle from +z)
    from bottom to top; each ring repeats its first vertex to close the seam."""
    phi = np.linspace(0.0, 2 * np.pi, segments + 1)
    pos, nrm = [], []
    for r, z, a in rings:
        pos.append(np.stack([r * np.cos(phi), r * np.sin(phi), np.full_like(phi, z)], 1))
        nrm.append(
            np.stack(
                [np.sin(a) * np.cos(phi), np.sin(a) * np.sin(phi), np.full_like(phi, np.cos(a))], 1
            )
        )
    n = segments + 1
    tri = []
    for i in range(len(rings) - 1):
        for j in range(segments):
            a, b = i * n + j, i * n + j + 1
            c, d = a + n, b + n
            tri += [(a, b, d), (a, d, c)]
    return np.concatenate(pos), np.concatenate(nrm), np.array(tri, np.int64)


def sphere(radius: float, segments: int = SEGMENTS):
    """A UV sphere."""
    k = segments // 2
    th = np.linspace(np.pi, 0.0, k + 1)  # from the bottom pole up
    return _grid([(radius * np.sin(t), radius * np.cos(t), t) for t in th], segments)


def ellipsoid(radii, segments: int = SEGMENTS):
    """A UV sphere scaled by ``radii`` (normals transformed by the inverse scale)."""
    p, n, t = sphere(1.0, segments)
    r = np.asarray(radii, float)
    n = n / r
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    return p * r, n, t


def capsule(radius: float, half_length: float, segments: int = SEGMENTS):
    """A cylinder of half-length ``half_length`` along z capped by hemispheres."""
    k = segments // 4
    rings = []
    for t in np.linspace(np.pi, np.pi / 2, k + 1):
        rings.append((radius * np.sin(t), -half_length + radius * np.cos(t), t))
    for t in np.linspace(np.pi / 2, 0.0, k + 1):
        rings.append((radius * np.sin(t), half_length + radius * np.cos(t), t))
    return _grid(rings, segments)


def _disk(radius: float, z: float, up: bool, segments: int):
    phi = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    rim = np.stack([radius * np.cos(phi), radius * np.sin(phi), np.full_like(phi, z)], 1)
    pos = np.vstack([[0.0, 0.0, z], rim])
    nrm = np.tile([0.0, 0.0, 1.0 if up else -1.0], (segments + 1, 1))
    j = np.arange(segments)
    a, b = 1 + j, 1 + (j + 1) % segments
    tri = np.stack(
        [np.zeros(segments, np.int64), a, b] if up else [np.zeros(segments, np.int64), b, a], 1
    )
    return pos, nrm, tri


def cylinder(radius: float, half_length: float, segments: int = SEGMENTS):
    """A closed cylinder of half-length ``half_length`` along z."""
    side = _grid([(radius, -half_length, np.pi / 2), (radius, half_length, np.pi / 2)], segments)
    return merge(
        [
            side,
            _disk(radius, -half_length, False, segments),
            _disk(radius, half_length, True, segments),
        ]
    )


def box(half_sizes):
    """A box with flat-shaded faces (4 vertices each)."""
    h = np.asarray(half_sizes, float)
    pos, nrm, tri = [], [], []
    for axis in range(3):
        for sign in (1.0, -1.0):
            n = np.zeros(3)
            n[axis] = sign
            u, v = np.zeros(3), np.zeros(3)
            u[(axis + 1) % 3], v[(axis + 2) % 3] = 1.0, 1.0
            if sign < 0:
                u, v = v, u
            c = n * h
            corners = [
                c + su * u * h + sv * v * h for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1))
            ]
            base = len(pos)
            pos += corners
            nrm += [n] * 4
            tri += [(base, base + 1, base + 2), (base, base + 2, base + 3)]
    return np.array(pos), np.array(nrm), np.array(tri, np.int64)


def merge(parts):
    """Concatenate meshes, offsetting the triangle indices."""
    pos, nrm, tri, off = [], [], [], 0
    for p, n, t in parts:
        pos.append(p)
        nrm.append(n)
        tri.append(t + off)
        off += len(p)
    return np.concatenate(pos), np.concatenate(nrm), np.concatenate(tri)


def geom_mesh(model: mujoco.MjModel, g: int, segments: int = SEGMENTS):
    """Geom ``g`` tessellated in its body's frame (placed by ``geom_pos`` / ``geom_quat``),
    or None for a type this module does not draw (planes, height fields, SDFs)."""
    t, size = model.geom_type[g], model.geom_size[g]
    T = mujoco.mjtGeom
    if t == T.mjGEOM_SPHERE:
        p, n, tri = sphere(size[0], segments)
    elif t == T.mjGEOM_ELLIPSOID:
        p, n, tri = ellipsoid(size[:3], segments)
    elif t == T.mjGEOM_CAPSULE:
        p, n, tri = capsule(size[0], size[1], segments)
    elif t == T.mjGEOM_CYLINDER:
        p, n, tri = cylinder(size[0], size[1], segments)
    elif t == T.mjGEOM_BOX:
        p, n, tri = box(size[:3])
    elif t == T.mjGEOM_MESH:
        m = model.geom_dataid[g]
        va, vn = model.mesh_vertadr[m], model.mesh_vertnum[m]
        fa, fn = model.mesh_faceadr[m], model.mesh_facenum[m]
        p = model.mesh_vert[va : va + vn].astype(float)
        tri = model.mesh_face[fa : fa + fn].astype(np.int64)
        p, tri = p[tri].reshape(-1, 3), np.arange(3 * fn).reshape(-1, 3)  # flat shaded
        e1, e2 = p[1::3] - p[0::3], p[2::3] - p[0::3]
        fnrm = np.cross(e1, e2)
        fnrm /= np.maximum(np.linalg.norm(fnrm, axis=1, keepdims=True), 1e-12)
        n = np.repeat(fnrm, 3, axis=0)
    else:
        return None
    R = np.empty(9)
    mujoco.mju_quat2Mat(R, model.geom_quat[g])
    R = R.reshape(3, 3)
    return p @ R.T + model.geom_pos[g], n @ R.T, tri
